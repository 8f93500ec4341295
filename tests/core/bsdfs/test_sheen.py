"""The sheen lobe of core/bsdfs/sheen.py inside core.bsdfs.bsdf: its table against fresh
random walks through the fibre layer, sampling against the pdf by
chi-square, normalisation, energy (white furnace), sample weights, grazing
angles, and batches against one row at a time."""

import importlib.util
import pathlib

import numpy as np
import pytest

from support.chi2 import ChiSquareTest, integrate, spherical_domain
from restir_gi.core.bsdfs import bsdf, sheen, velvet
from restir_gi.core.materials.shading import params_of
from restir_gi.core.materials.shader.closure import Closure

HEMISPHERE = spherical_domain(cos_range=(0.0, 1.0))
N = 300_000
ROUGH = (0.1, 0.5, 1.0)
COS_WO = (0.95, 0.5, 0.1)
PHI_WO = 0.7


def direction(cos_theta, phi=PHI_WO):
    s = np.sqrt(max(1 - cos_theta * cos_theta, 0.0))
    return np.array([s * np.cos(phi), s * np.sin(phi), cos_theta])


def rep(v, n):
    return np.ascontiguousarray(np.broadcast_to(np.asarray(v, np.float32), (n, 3)))


def closure(rough, tint=(1.0, 1.0, 1.0), base=None):
    """A sheen on its own, or over a Principled-like base (Lambert under a
    dielectric layer of f0 0.04, roughness 0.5)."""
    c = Closure.bsdf(sheen=np.asarray(tint, np.float32), sheen_rough=rough)
    if base is not None:
        c = c + Closure.bsdf(layered=np.asarray(base, np.float32), layer_f0=0.04,
                             specular=np.full(3, 0.04, np.float32), spec_edge=np.ones(3, np.float32),
                             spec_rough=0.5)
    return c


def params(c, n, wo):
    return bsdf.at_view(params_of(c, n), rep(wo, n))


def draw(c, wo, rng, n=N):
    p = params(c, n, wo)
    wo_b = rep(wo, n)
    wi, f, pdf = bsdf.sample(p, wo_b, rng.random(n, dtype=np.float32), rng.random((n, 2), dtype=np.float32))
    return p, wo_b, wi, f, pdf


def pdf_fn(c, wo):
    def fn(w):
        w = np.asarray(w, np.float32)
        return bsdf.pdf(params(c, len(w), wo), rep(wo, len(w)), w)
    return fn


def albedo(c, wo):
    def fn(w):
        w = np.asarray(w, np.float32)
        f = bsdf.evaluate(params(c, len(w), wo), rep(wo, len(w)), w)
        return f * np.maximum(w[:, 2], 0.0)[:, None]
    return integrate(fn, HEMISPHERE, res=(24, 24))


def test01_table_matches_fresh_random_walks(rng):
    """R of the stored table against new walks through the fibre layer
    (tools/fit_sheen.py), at nodes of the table, within the walks' noise."""
    path = pathlib.Path(__file__).resolve().parents[3] / "tools" / "fit_sheen.py"
    spec = importlib.util.spec_from_file_location("fit_sheen", path)
    fit = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fit)
    t = sheen.table()
    assert t.shape == (32, 32, 3) and np.isfinite(t).all()
    assert (t[..., 0] > 0).all() and (t[..., 2] >= 0).all() and (t[..., 2] <= 1).all()
    n = 40_000
    for i, j in ((31, 0), (31, 31), (16, 10), (8, 3), (24, 20)):
        rough, cos = fit.grid()[0][i], fit.grid()[1][j]
        reflected, _ = fit.walk(np.full(n, cos), np.full(n, rough), rng)
        r = reflected.mean()
        assert abs(r - t[i, j, 2]) < 4 * np.sqrt(r * (1 - r) / n) + 4 * 0.0025 + 1e-4, (i, j, r, t[i, j, 2])


CASES = [(r, c) for r in ROUGH for c in COS_WO]


@pytest.mark.parametrize("rough,cos_wo", CASES)
def test02_sample_matches_pdf_chi2(rough, cos_wo, rng):
    wo = direction(cos_wo)
    c = closure(rough)
    _, _, wi, _, pdf = draw(c, wo, rng)
    assert (wi[pdf > 0, 2] > 0).all()
    samples = np.where((pdf > 0)[:, None], wi, np.nan)
    test = ChiSquareTest(lambda n: samples, pdf_fn(c, wo), HEMISPHERE, res=(24, 24), sample_count=N,
                         test_count=len(CASES) + 1)
    assert test.run()


def test03_sample_matches_pdf_over_a_base_chi2(rng):
    """Lobe choice between sheen, GGX and Lambert: the mixture's pdf."""
    wo = direction(0.4)
    c = closure(0.4, tint=(0.9, 0.7, 0.5), base=(0.05, 0.05, 0.08))
    p, _, wi, _, pdf = draw(c, wo, rng)
    assert 0.2 < p.p_sheen[0] < 0.95
    samples = np.where((pdf > 0)[:, None], wi, np.nan)
    test = ChiSquareTest(lambda n: samples, pdf_fn(c, wo), HEMISPHERE, res=(24, 24), sample_count=N,
                         test_count=len(CASES) + 1)
    assert test.run()


@pytest.mark.parametrize("rough", ROUGH)
def test04_pdf_integrates_to_one(rough):
    for cos_wo in (1.0,) + COS_WO + (0.01,):
        total = integrate(pdf_fn(closure(rough), direction(cos_wo)), HEMISPHERE, res=(24, 24))
        assert total == pytest.approx(1.0, abs=2e-3), cos_wo


@pytest.mark.parametrize("rough", ROUGH)
def test05_albedo_is_the_tables_and_white_furnace(rough):
    """A sheen alone reflects R x tint; over a white base the base gets
    1 - R, so a white Principled-like surface stays at or below one."""
    for cos_wo in COS_WO:
        wo = direction(cos_wo)
        r = sheen.ltc_terms(np.float32(rough), np.float32(cos_wo))[2]
        assert np.allclose(albedo(closure(rough, tint=(1.0, 0.5, 0.25)), wo), r * np.array([1.0, 0.5, 0.25]),
                           rtol=3e-3, atol=1e-4)
        white = albedo(closure(rough, base=(1.0, 1.0, 1.0)), wo)
        assert (white <= 1.0 + 0.015).all() and (white >= 0.93).all(), (cos_wo, white)


@pytest.mark.parametrize("rough", ROUGH)
def test06_sample_weights(rough, rng):
    """A sheen sample's weight f cos / pdf is its albedo R x tint exactly;
    sample() agrees with evaluate() and pdf()."""
    for cos_wo in COS_WO:
        wo = direction(cos_wo)
        c = closure(rough, tint=(0.8, 0.6, 0.4))
        p, wo_b, wi, f, pdf = draw(c, wo, rng, n=50_000)
        assert np.allclose(f, bsdf.evaluate(p, wo_b, wi), rtol=1e-6, atol=1e-7)
        assert np.allclose(pdf, bsdf.pdf(p, wo_b, wi), rtol=1e-6, atol=1e-7)
        ok = pdf > 0
        assert ok.mean() > 0.999
        weight = f[ok] * wi[ok, 2:3] / pdf[ok, None]
        assert np.allclose(weight, p.sheen[0], rtol=2e-3, atol=1e-6)


def test07_no_nan_at_grazing_angles(rng):
    n = 4096
    c = closure(0.3, base=(0.5, 0.5, 0.5))
    for cos_wo in (1.0, 1e-3, 1e-6, 0.0, -0.2):
        wo = rep(direction(cos_wo), n)
        p = params(c, n, direction(cos_wo))
        wi = rng.normal(size=(n, 3))
        wi[:, 2] = np.abs(wi[:, 2]) * rng.choice([0.0, 1e-7, 1e-3, 1.0], n)
        wi = (wi / np.linalg.norm(wi, axis=1, keepdims=True)).astype(np.float32)
        f, pdf = bsdf.evaluate_pdf(p, wo, wi)
        s_wi, s_f, s_pdf = bsdf.sample(p, wo, rng.random(n, dtype=np.float32), rng.random((n, 2), dtype=np.float32))
        for a in (f, pdf, s_wi, s_f, s_pdf):
            assert np.isfinite(a).all(), cos_wo
        assert (f >= 0).all() and (pdf >= 0).all()


def test08_batch_equals_one_at_a_time(rng):
    """Rows with and without sheen in one batch, against each row alone."""
    n = 40
    cs = [closure(0.3), closure(0.8, tint=(0.2, 0.9, 0.4), base=(0.1, 0.1, 0.1)),
          Closure.bsdf(diffuse=np.full(3, 0.5, np.float32))]
    pick = rng.integers(0, len(cs), n)
    wo = rng.normal(size=(n, 3))
    wo[: n // 2, 2] = np.abs(wo[: n // 2, 2])
    wo = (wo / np.linalg.norm(wo, axis=1, keepdims=True)).astype(np.float32)
    wi = rng.normal(size=(n, 3))
    wi = (wi / np.linalg.norm(wi, axis=1, keepdims=True)).astype(np.float32)
    u_lobe, u = rng.random(n, dtype=np.float32), rng.random((n, 2), dtype=np.float32)
    rows = [params_of(cs[k], 1) for k in pick]
    full = params_of(cs[1], 1)          # every field present
    p = params_of(cs[0], n)
    for name in ("diffuse", "f0", "f90", "alpha", "p_spec", "layered", "layer_f0", "sheen", "sheen_rough"):
        setattr(p, name, np.concatenate([getattr(r, name) if getattr(r, name) is not None
                                         else np.zeros_like(getattr(full, name)) for r in rows]))
    bsdf.at_view(p, wo)
    f, pdf = bsdf.evaluate(p, wo, wi), bsdf.pdf(p, wo, wi)
    s_wi, s_f, s_pdf = bsdf.sample(p, wo, u_lobe, u)
    for i in range(n):
        q = p.subset(np.array([i]))
        one = slice(i, i + 1)
        assert np.allclose(bsdf.evaluate(q, wo[one], wi[one]), f[one], rtol=1e-5, atol=1e-7)
        assert np.allclose(bsdf.pdf(q, wo[one], wi[one]), pdf[one], rtol=1e-5, atol=1e-7)
        w1, f1, p1 = bsdf.sample(q, wo[one], u_lobe[one], u[one])
        assert np.allclose(w1, s_wi[one], atol=1e-6)
        assert np.allclose(f1, s_f[one], rtol=1e-5, atol=1e-7)
        assert np.allclose(p1, s_pdf[one], rtol=1e-5, atol=1e-7)


# --- the Sheen BSDF node ---------------------------------------------------------------

def test09_sheen_node_dims_nothing_below(rng):
    """The Sheen BSDF node's Microfiber is the same lobe, but on top of
    nothing: a diffuse added to it keeps its whole albedo (the Principled
    sheen's layering dims it by the sheen's albedo)."""
    base = Closure.bsdf(diffuse=np.full(3, 0.5, np.float32))
    wo = direction(0.4)
    layered = params(closure(0.5) + base, 1, wo)
    node = params(Closure.bsdf(sheen=np.ones(3, np.float32), sheen_rough=0.5, sheen_free=np.float32(1)) + base,
                  1, wo)
    assert np.allclose(node.diffuse, 0.5) and (layered.diffuse < 0.5).all()
    assert np.allclose(node.sheen, layered.sheen)        # the same lobe
    # Half and half: dimmed by half the sheen's albedo.
    half = params(closure(0.5).scaled(0.5) + Closure.bsdf(sheen=np.full(3, 0.5, np.float32), sheen_rough=0.5,
                                                         sheen_free=np.float32(1)) + base, 1, wo)
    assert np.allclose(0.5 - half.diffuse, (0.5 - layered.diffuse) / 2, rtol=1e-5)


def _velvet_scalar(wo, wi, sigma):
    """Cycles' bsdf_ashikhmin_velvet_eval, one pair at a time (its wi is the
    view, here wo), divided by the light's cosine."""
    cos_view, cos_light = wo[2], wi[2]
    if not (cos_view > 0 and cos_light > 0):
        return 0.0
    h = (wo + wi) / np.linalg.norm(wo + wi)
    cos_nh, cos_hi = h[2], abs(wo @ h)
    if not (abs(cos_nh) < 1 - 1e-5 and cos_hi > 1e-5):
        return 0.0
    r = max(cos_nh / cos_hi, 1e-5)
    inv_s2 = 1 / max(sigma, 0.01) ** 2
    sin2 = 1 - cos_nh * cos_nh
    d = np.exp(-(cos_nh * cos_nh / sin2) * inv_s2) * inv_s2 / np.pi / (sin2 * sin2)
    g = min(1.0, 2 * r * cos_light, 2 * r * cos_view)
    return 0.25 * d * g / cos_view / cos_light


def test10_ashikhmin_is_cycles_velvet(rng):
    """The Sheen node's Ashikhmin distribution: Cycles' Ashikhmin velvet, by
    its formula (and reciprocal); its cosine samples (the diffuse lobe's
    share) estimate the albedo a uniform quadrature of f cos gives."""
    n = 400
    wo, wi = (rng.normal(size=(n, 3)) for _ in range(2))
    wo[:, 2], wi[:, 2] = np.abs(wo[:, 2]), np.where(np.arange(n) < 20, -1, 1) * np.abs(wi[:, 2])
    wo, wi = ((v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32) for v in (wo, wi))
    sigma = rng.uniform(0.0, 1.0, n).astype(np.float32)
    got = velvet.velvet_f(wo, wi, sigma)
    want = [_velvet_scalar(wo[i].astype(np.float64), wi[i].astype(np.float64), float(sigma[i])) for i in range(n)]
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=1e-6)
    np.testing.assert_allclose(velvet.velvet_f(wi, wo, sigma), got, rtol=2e-4, atol=1e-6)
    for rough, cos_wo in ((0.35, 0.2), (0.6, 0.5), (1.0, 0.95)):
        c = Closure.bsdf(velvet=np.array([0.9, 0.6, 0.3], np.float32), velvet_sigma=rough)
        p, wo_b, s_wi, s_f, s_pdf = draw(c, direction(cos_wo), rng)
        est = np.where((s_pdf > 0)[:, None], s_f * (s_wi[:, 2] / np.where(s_pdf > 0, s_pdf, 1))[:, None], 0)
        u = rng.random((N, 2))
        z = u[:, 0]
        r = np.sqrt(np.maximum(1 - z * z, 0))
        uni = np.stack([r * np.cos(2 * np.pi * u[:, 1]), r * np.sin(2 * np.pi * u[:, 1]), z], 1).astype(np.float32)
        quad = bsdf.evaluate(p, wo_b, uni) * (z * 2 * np.pi)[:, None]
        a, b = est.mean(axis=0), quad.mean(axis=0)
        err = np.hypot(est.std(axis=0), quad.std(axis=0)) / np.sqrt(N)
        assert (np.abs(a - b) < 4.5 * err).all() and (a > 0.02).all(), (rough, cos_wo, a, b, err)
