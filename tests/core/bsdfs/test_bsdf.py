"""The Lambert + GGX BSDF of core.bsdfs.bsdf: sample against pdf by chi-square,
normalisation, reciprocity, energy (white furnace), sample weights, and batch
against one-at-a-time evaluation (Mitsuba's test_diffuse / test_roughconductor
and check_vectorization)."""

import numpy as np
import pytest

from support.chi2 import ChiSquareTest, integrate, log_spherical_domain, spherical_domain
from restir_gi.core import Materials
from restir_gi.core.bsdfs import bsdf, principled

MATERIALS = {
    "lambert": {"base_color": (0.8, 0.6, 0.3), "specular": 0.0, "metallic": 0.0},
    "dielectric_r0.2": {"base_color": (0.8, 0.6, 0.3), "specular": 0.5, "roughness": 0.2, "ior": 1.5},
    "dielectric_r0.6": {"base_color": (0.8, 0.6, 0.3), "specular": 0.5, "roughness": 0.6, "ior": 1.5},
    "metal_r0.1": {"base_color": (0.9, 0.6, 0.3), "metallic": 1.0, "roughness": 0.1},
    "metal_r0.5": {"base_color": (0.9, 0.6, 0.3), "metallic": 1.0, "roughness": 0.5},
}
NAMES = list(MATERIALS)
COS_WO = (0.95, 0.6, 0.25)
PHI_WO = 0.7
N = 400_000
HEMISPHERE = spherical_domain(cos_range=(0.0, 1.0))


def params(name, n, white=False, wo=None):
    """BSDFParams of a material for n rows, seen from wo (as ShadingFrame makes them)."""
    row = dict(MATERIALS[name])
    if white:
        row["base_color"] = (1.0, 1.0, 1.0)
    p = principled.bsdf_params(Materials.from_list([row]), np.zeros(n, np.int32))
    return p if wo is None else bsdf.at_view(p, rep(wo, n))


def direction(cos_theta, phi=PHI_WO):
    s = np.sqrt(1 - cos_theta * cos_theta)
    return np.array([s * np.cos(phi), s * np.sin(phi), cos_theta])


def rep(v, n):
    return np.ascontiguousarray(np.broadcast_to(np.asarray(v, np.float32), (n, 3)))


def pdf_fn(name, wo):
    def fn(w):
        w = np.asarray(w, np.float32)
        return bsdf.pdf(params(name, len(w), wo=wo), rep(wo, len(w)), w)
    return fn


def cos_weighted_f(name, wo, white=False):
    def fn(w):
        w = np.asarray(w, np.float32)
        f = bsdf.evaluate(params(name, len(w), white, wo), rep(wo, len(w)), w)
        return f * np.maximum(w[:, 2], 0.0)[:, None]
    return fn


def draw(name, wo, rng, n=N, white=False):
    p = params(name, n, white, wo)
    wo_b = rep(wo, n)
    u_lobe = rng.random(n, dtype=np.float32)
    u = rng.random((n, 2), dtype=np.float32)
    wi, f, pdf = bsdf.sample(p, wo_b, u_lobe, u)
    return p, wo_b, wi, f, pdf


def test01_params_follow_the_principled_subset():
    mats = Materials.from_list([MATERIALS[k] for k in NAMES])
    p = principled.bsdf_params(mats, np.arange(len(NAMES), dtype=np.int32))
    lam, d02, _, m01, _ = range(5)
    assert p.p_spec[lam] == 0 and np.allclose(p.f0[lam], 0) and np.allclose(p.diffuse[lam], [0.8, 0.6, 0.3])
    # Specular 0.5 at IOR 1.5: F0 = ((1.5 - 1) / (1.5 + 1))^2 = 0.04.
    assert np.allclose(p.f0[d02], 0.04, atol=1e-6)
    # The whole base colour, under a layer of f0 0.04 (at_view takes the layer's share).
    assert np.allclose(p.diffuse[d02], [0.8, 0.6, 0.3], atol=1e-6)
    assert np.allclose(p.layered[d02], [0.8, 0.6, 0.3], atol=1e-6) and np.isclose(p.layer_f0[d02], 0.04)
    assert 0.1 <= p.p_spec[d02] <= 0.9
    assert np.allclose(p.diffuse[m01], 0) and np.allclose(p.f0[m01], [0.9, 0.6, 0.3]) and p.p_spec[m01] == 1
    assert p.alpha[m01] == pytest.approx(0.01)


# --- sampling against the density ---------------------------------------------------

SHARP = ("dielectric_r0.2", "metal_r0.1")


def _domains(name, wo):
    """The hemisphere in (cos theta, phi) about the normal (horizon on a bin edge),
    and for sharp lobes also (log(1 - cos), phi) about the mirror direction, whose
    bins resolve them: a cap that stops short of the horizon, the rest of the
    sphere being the outside cell."""
    out = [("normal", HEMISPHERE, (24, 24))]
    if name in SHARP:
        mirror = 2 * wo[2] * np.array([0, 0, 1.0]) - wo
        elevation = np.arcsin(mirror[2])
        out.append(("mirror", log_spherical_domain(mirror, max_angle=0.9 * elevation), (28, 24)))
    return out


CASES = [(name, c, which) for name in NAMES for c in COS_WO
         for which in (["normal", "mirror"] if name in SHARP else ["normal"])]


@pytest.mark.slow
@pytest.mark.parametrize("name,cos_wo,which", CASES)
def test02_sample_matches_pdf_chi2(name, cos_wo, which, rng):
    wo = direction(cos_wo)
    _, dom, res = next(d for d in _domains(name, wo) if d[0] == which)
    _, _, wi, _, pdf = draw(name, wo, rng)
    assert (wi[pdf > 0, 2] > 0).all()
    samples = np.where((pdf > 0)[:, None], wi, np.nan)      # lost samples go to the outside cell
    test = ChiSquareTest(lambda n: samples, pdf_fn(name, wo), dom, res=res, sample_count=N,
                         test_count=len(CASES))
    assert test.run()


@pytest.mark.parametrize("name", NAMES)
def test03_pdf_integrates_to_one_minus_lost_mass(name, rng):
    for cos_wo in COS_WO:
        wo = direction(cos_wo)
        total = integrate(pdf_fn(name, wo), HEMISPHERE, res=(24, 24))
        _, _, _, _, pdf = draw(name, wo, rng, n=100_000)
        kept = (pdf > 0).mean()
        assert total <= 1.0 + 1e-4
        assert total == pytest.approx(kept, abs=4 * np.sqrt(kept * (1 - kept) / len(pdf)) + 1e-3)
        if name == "lambert":
            assert total == pytest.approx(1.0, abs=1e-4)
    # Below the horizon no direction is ever sampled or has density.
    below = rep(-direction(0.5), 8)
    assert (bsdf.pdf(params(name, 8), rep(direction(0.5), 8), below) == 0).all()


@pytest.mark.parametrize("name", NAMES)
def test04_reciprocity(name, rng):
    n = 20000
    a = rng.normal(size=(n, 3))
    b = rng.normal(size=(n, 3))
    a[:, 2], b[:, 2] = np.abs(a[:, 2]) + 1e-3, np.abs(b[:, 2]) + 1e-3
    a = (a / np.linalg.norm(a, axis=1, keepdims=True)).astype(np.float32)
    b = (b / np.linalg.norm(b, axis=1, keepdims=True)).astype(np.float32)
    p = params(name, n)
    f_ab, f_ba = bsdf.evaluate(p, a, b), bsdf.evaluate(p, b, a)
    assert (f_ab >= 0).all() and np.isfinite(f_ab).all()
    assert np.allclose(f_ab, f_ba, rtol=2e-4, atol=1e-6)


# --- energy ---------------------------------------------------------------------------

def albedo(name, wo, white=False):
    """(3,) integral of f cos over the hemisphere."""
    return integrate(cos_weighted_f(name, wo, white), HEMISPHERE, res=(24, 24))


def test05_lambert_albedo_is_the_base_colour():
    for cos_wo in (1.0, 0.5, 0.1):
        assert np.allclose(albedo("lambert", direction(cos_wo)), [0.8, 0.6, 0.3], atol=1e-4)


@pytest.mark.parametrize("name", ["lambert", "metal_r0.1", "metal_r0.5"])
def test06_white_furnace(name):
    """A white surface reflects all it receives: multiple-scattering energy
    put back into the GGX lobe (core/bsdfs/microfacet_albedo.py) brings white metals
    to one, within the accuracy of the albedo table."""
    # (A 24 x 24 quadrature misses part of the sharp roughness-0.1 lobe.)
    low = 0.8 if name == "metal_r0.1" else 0.97
    for cos_wo in (1.0, 0.8, 0.5, 0.3, 0.1):
        a = albedo(name, direction(cos_wo), white=True)
        assert (a <= 1.0 + 0.015).all() and (a >= low).all(), (cos_wo, a)


@pytest.mark.parametrize("name", ["dielectric_r0.2", "dielectric_r0.6"])
def test07_white_furnace_dielectric_at_normal_incidence(name):
    a = albedo(name, direction(1.0), white=True)
    assert (0.97 < a).all() and (a <= 1.0 + 0.015).all()


@pytest.mark.parametrize("name", ["dielectric_r0.2", "dielectric_r0.6"])
def test08_white_furnace_dielectric_at_grazing_angles(name):
    """The diffuse base keeps only what the specular layer does not reflect at
    the viewing angle (Cycles' layering), so a white dielectric neither gains
    nor loses energy toward grazing views."""
    for cos_wo in (0.6, 0.3, 0.1):
        a = albedo(name, direction(cos_wo), white=True)
        assert (a <= 1.0 + 0.015).all() and (a >= 0.95).all(), (cos_wo, a)


@pytest.mark.parametrize("name", NAMES)
def test09_sample_weights(name, rng):
    """The sample's f and pdf are evaluate() and pdf() at its wi, and the mean of
    f cos / pdf (zero for lost samples) converges to the albedo integral."""
    for cos_wo in COS_WO:
        wo = direction(cos_wo)
        p, wo_b, wi, f, pdf = draw(name, wo, rng, n=200_000)
        assert np.allclose(f, bsdf.evaluate(p, wo_b, wi), rtol=1e-6, atol=1e-7)
        assert np.allclose(pdf, bsdf.pdf(p, wo_b, wi), rtol=1e-6, atol=1e-7)
        ok = pdf > 0
        weight = np.where(ok[:, None], f * np.maximum(wi[:, 2], 0)[:, None] / np.where(ok, pdf, 1)[:, None], 0)
        assert np.isfinite(weight).all() and (weight >= 0).all()
        est = weight.mean(axis=0, dtype=np.float64)
        err = weight.std(axis=0, dtype=np.float64) / np.sqrt(len(weight))
        ref = albedo(name, wo)
        assert (np.abs(est - ref) < 4.5 * err + 2e-4).all(), (est, ref, err)


# --- vectorised against scalar -----------------------------------------------------------

def test10_batch_equals_one_at_a_time(rng):
    n = 60
    mats = Materials.from_list([MATERIALS[k] for k in NAMES])
    p = principled.bsdf_params(mats, rng.integers(0, len(NAMES), n).astype(np.int32))
    wo = rng.normal(size=(n, 3))
    wo[: n // 2, 2] = np.abs(wo[: n // 2, 2])           # most above, some below the normal
    wo = (wo / np.linalg.norm(wo, axis=1, keepdims=True)).astype(np.float32)
    wi = rng.normal(size=(n, 3))
    wi = (wi / np.linalg.norm(wi, axis=1, keepdims=True)).astype(np.float32)
    u_lobe = rng.random(n, dtype=np.float32)
    u = rng.random((n, 2), dtype=np.float32)

    f, pdf = bsdf.evaluate(p, wo, wi), bsdf.pdf(p, wo, wi)
    s_wi, s_f, s_pdf = bsdf.sample(p, wo, u_lobe, u)
    for i in range(n):
        q = p.subset(np.array([i]))
        one = slice(i, i + 1)
        assert np.allclose(bsdf.evaluate(q, wo[one], wi[one]), f[one], rtol=1e-6, atol=1e-8)
        assert np.allclose(bsdf.pdf(q, wo[one], wi[one]), pdf[one], rtol=1e-6, atol=1e-8)
        w1, f1, p1 = bsdf.sample(q, wo[one], u_lobe[one], u[one])
        assert np.allclose(w1, s_wi[one], atol=1e-6)
        assert np.allclose(f1, s_f[one], rtol=1e-5, atol=1e-7)
        assert np.allclose(p1, s_pdf[one], rtol=1e-5, atol=1e-7)


def test11_lobe_params_without_glass_warn_nothing():
    """Diffuse and specular alone (no glass lobe, whose weight is then the
    Python float 0): no warning, on Python 3.13 either, where inverting a
    Python bool with '~' is deprecated."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p = bsdf.lobe_params(np.full((2, 3), 0.5, np.float32), np.full((2, 3), 0.04, np.float32),
                             np.float32([0.3, 0.7]))
    assert np.all((p.p_spec >= 0.1) & (p.p_spec <= 0.9))
