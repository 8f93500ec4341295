"""The GGX dielectric of core.bsdfs.glass (Cycles' Glass BSDF): Fresnel values,
eval against a scalar transcription of Walter et al. 2007, sample against eval,
chi-square over the whole sphere, energy (smooth limit and white furnace), the
reciprocity of each transport mode, and degenerate input."""

import math

import numpy as np
import pytest

from support.chi2 import ChiSquareTest, integrate, log_spherical_domain, spherical_domain
from restir_gi.core.bsdfs import glass as glass
from restir_gi.core.bsdfs.microfacet import ALPHA_MIN
from support.optics import fresnel_ref

PHI_WO = 0.7
N = 400_000


def direction(cos_theta, phi=PHI_WO):
    s = math.sqrt(max(0.0, 1 - cos_theta * cos_theta))
    return np.array([s * math.cos(phi), s * math.sin(phi), cos_theta])


def rep(v, n):
    return np.ascontiguousarray(np.broadcast_to(np.asarray(v, np.float32), (n, 3)))


def col(x, n):
    return np.full(n, x, np.float32)


def unit(rng, n, z_sign=None):
    w = rng.normal(size=(n, 3))
    if z_sign is not None:
        w[:, 2] = z_sign * (np.abs(w[:, 2]) + 1e-2)
    return (w / np.linalg.norm(w, axis=1, keepdims=True)).astype(np.float32)


def draw(wo, alpha, eta, rng, n=N, tint=(1, 1, 1), radiance=True):
    wo_b = rep(wo, n)
    wi, f, pdf = glass.glass_sample(wo_b, col(alpha, n), col(eta, n), rep(tint, n),
                                    rng.random(n, dtype=np.float32),
                                    rng.random((n, 2), dtype=np.float32), radiance)
    return wo_b, wi, f, pdf


def weights(wi, f, pdf):
    """f |wi.z| / pdf of the red channel, zero for lost samples."""
    ok = pdf > 0
    return np.where(ok, f[:, 0] * np.abs(wi[:, 2]) / np.where(ok, pdf, 1), 0.0).astype(np.float64)


# --- plain scalar formulas, written independently of the module --------------------

def ggx_d_ref(cos_h, a):
    c2 = cos_h * cos_h
    return a * a / (math.pi * (c2 * (a * a - 1) + 1) ** 2) if cos_h > 0 else 0.0


def lambda_ref(cos_w, a):
    c2 = cos_w * cos_w
    return 0.5 * (math.sqrt(1 + a * a * (1 - c2) / c2) - 1)


def walter_ref(o, i, a, eta):
    """(f, pdf) of Walter et al. 2007 for one pair, in its notation: o the viewer
    direction in the medium eta_o = 1, i the light direction (eta_i = eta on the
    far side). Eq. 20 (reflection), 21 (refraction, radiance), 14/17 (Jacobians),
    pdf by visible normals times the Fresnel choice. 0 where no microfacet connects them."""
    o, i = np.asarray(o, np.float64), np.asarray(i, np.float64)
    eta_o, eta_i = 1.0, (eta if i[2] < 0 else 1.0)
    h = -(eta_i * i + eta_o * o) if i[2] < 0 else i + o
    h = h / np.linalg.norm(h) * math.copysign(1.0, h[2])
    oh, ih = float(o @ h), float(i @ h)
    if o[2] <= 0 or oh <= 0 or (i[2] < 0) != (ih < 0):
        return 0.0, 0.0
    F = fresnel_ref(math.acos(min(oh, 1.0)), eta)
    D = ggx_d_ref(h[2], a)
    G1 = 1 / (1 + lambda_ref(o[2], a))
    G2 = 1 / (1 + lambda_ref(o[2], a) + lambda_ref(i[2], a))
    d_wo = G1 * oh * D / o[2]
    if i[2] > 0:
        return F * D * G2 / (4 * o[2] * i[2]), F * d_wo / (4 * oh)
    den = (eta_i * ih + eta_o * oh) ** 2
    f = abs(ih) * abs(oh) / (abs(i[2]) * o[2]) * eta_o ** 2 * (1 - F) * G2 * D / den
    return f, (1 - F) * d_wo * eta_i ** 2 * abs(ih) / den


# --- 2. eval against the scalar reference, sample against eval -----------------------------

@pytest.mark.parametrize("radiance", [True, False])
def test02_eval_matches_walter(radiance, rng):
    n = 300
    wo = unit(rng, n, +1)
    wi = unit(rng, n)
    alpha = rng.uniform(0.05, 0.8, n).astype(np.float32)
    eta = rng.choice(np.float32([1.5, 1 / 1.5, 1.33, 2.0]), n)
    tint = rng.uniform(0.2, 1, (n, 3)).astype(np.float32)
    f, pdf = glass.glass_eval(wo, wi, alpha, eta, tint, radiance)
    ref = np.array([walter_ref(wo[k], wi[k], alpha[k], eta[k]) for k in range(n)])
    ref_f = ref[:, 0] * np.where((wi[:, 2] < 0) & (not radiance), eta.astype(np.float64) ** 2, 1)
    assert (ref[:, 1] > 0).sum() > n / 3 and ((ref[:, 1] > 0) & (wi[:, 2] < 0)).sum() > n / 20
    assert np.allclose(pdf, ref[:, 1], rtol=2e-4, atol=1e-7)
    assert np.allclose(f, tint * ref_f[:, None], rtol=2e-4, atol=1e-7)


CONFIGS = [(a, e, c) for a in (0.25, 0.02) for e in (1.5, 1 / 1.5) for c in (0.9, 0.5, 0.15)] + [(0.3, 1.0, 0.5)]


@pytest.mark.parametrize("alpha,eta,cos_wo", CONFIGS)
def test03_sample_is_eval_at_its_direction(alpha, eta, cos_wo, rng):
    """f and pdf of a sample are glass_eval's at its wi; its weight f |wi.z| / pdf is
    tint G2 / G1(wo), over eta^2 when refracted. Samples reflect (unless eta = 1) and
    refract (unless total internal reflection), and lost ones have f = 0."""
    tint = (0.9, 0.5, 0.2)
    wo, wi, f, pdf = draw(direction(cos_wo), alpha, eta, rng, n=50_000, tint=tint)
    f_e, pdf_e = glass.glass_eval(wo, wi, col(alpha, len(wo)), col(eta, len(wo)), rep(tint, len(wo)))
    ok = pdf > 0
    assert ok.mean() > 0.8 and np.isfinite(wi).all() and np.allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-6)
    assert np.array_equal(pdf[ok], pdf_e[ok]) and np.array_equal(f[ok], f_e[ok])
    assert (f[~ok] == 0).all()
    refr = wi[:, 2] < 0
    assert ((ok & ~refr).any() or eta == 1) and ((ok & refr).any() or (eta < 1 and cos_wo < 0.8))
    a = ALPHA_MIN if eta == 1 else alpha                # index-matched: roughness dropped
    lam = [np.array([lambda_ref(float(z), a) for z in np.abs(w[ok, 2])]) for w in (wo, wi)]
    expect = (1 + lam[0]) / (1 + lam[0] + lam[1]) / np.where(refr[ok], eta * eta, 1.0)
    assert np.allclose(f[ok] * np.abs(wi[ok, 2:3]) / pdf[ok, None], np.outer(expect, tint), rtol=1e-4)


# --- 3. sampling against the density, over the whole sphere -----------------------------

SPHERE = spherical_domain(cos_range=(-1.0, 1.0))


def _refracted(wo, eta):
    """wo refracted through the macro-surface, or None under total internal reflection
    (-wo for index-matched eta, whose lobe does not bend)."""
    eta = 1.0 if abs(math.log(eta)) < math.log1p(glass.ETA_GAP) else eta
    s2 = (1 - wo[2] ** 2) / eta ** 2
    return None if s2 >= 1 else np.array([-wo[0] / eta, -wo[1] / eta, -math.sqrt(1 - s2)])


def _chi2_cases():
    """The sphere in (cos theta, phi) for rough lobes; for sharp ones a log-spaced cap
    about the mirror or the refracted direction, stopping short of the horizon."""
    out = []
    for alpha in (0.25, 0.1):
        for eta in (1.5, 1 / 1.5):
            for c in (0.9, 0.5, 0.15):
                out.append((alpha, eta, c, "sphere"))
    for eta in (1.5, 1 / 1.5):
        for c in (0.9, 0.5):
            out.append((0.02, eta, c, "mirror"))
            if _refracted(direction(c), eta) is not None:
                out.append((0.02, eta, c, "refracted"))
    for eta in (1.0, 1.0005):      # index-matched: the lobe at ALPHA_MIN about -wo
        out.append((0.5, eta, 0.5, "refracted"))
    return out


CHI2 = _chi2_cases()


def _domain(wo, eta, which):
    if which == "sphere":
        return SPHERE, (48, 24)
    axis = np.array([-wo[0], -wo[1], wo[2]]) if which == "mirror" else _refracted(wo, eta)
    return log_spherical_domain(axis, max_angle=0.9 * abs(math.asin(axis[2]))), (28, 24)


@pytest.mark.slow
@pytest.mark.parametrize("alpha,eta,cos_wo,which", CHI2)
def test04_sample_matches_pdf_chi2(alpha, eta, cos_wo, which, rng):
    wo = direction(cos_wo)
    dom, res = _domain(wo, eta, which)
    _, wi, _, pdf = draw(wo, alpha, eta, rng)
    samples = np.where((pdf > 0)[:, None], wi, np.nan)      # lost samples go to the outside cell

    def pdf_fn(w):
        w, n = np.asarray(w, np.float32), len(w)
        return glass.glass_eval(rep(wo, n), w, col(alpha, n), col(eta, n), rep((1, 1, 1), n))[1]

    test = ChiSquareTest(lambda n: samples, pdf_fn, dom, res=res, sample_count=N, test_count=len(CHI2))
    assert test.run()
    if which == "sphere":       # the density integrates to the kept fraction, at most 1
        kept = (pdf > 0).mean()
        assert test.integral <= 1 + 1e-4
        assert test.integral == pytest.approx(kept, abs=4 * math.sqrt(kept * (1 - kept) / N) + 1e-3)


# --- 4. energy ---------------------------------------------------------------------------

def fresnel_vec(cos_i, eta):
    """fresnel_ref on arrays, in float64 (the quadrature below needs millions)."""
    ti = np.arccos(np.clip(cos_i, -1, 1))
    s = np.sin(ti) / eta
    tt = np.arcsin(np.minimum(s, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (np.sin(ti - tt) / np.sin(ti + tt)) ** 2
        rp = (np.tan(ti - tt) / np.tan(ti + tt)) ** 2
    return np.where(s >= 1, 1.0, np.where(ti < 1e-6, ((eta - 1) / (eta + 1)) ** 2, 0.5 * (rs + rp)))


def albedo_by_normals(alpha, eta, cos_wo, res=(32, 16)):
    """E = R + eta^2 T (T: the refracted radiance, R: the reflected) of one rough
    interface, by quadrature over microfacet normals h rather than over wi:
        E = integral of (wo.h)+ D(h) / wo.z [F G2(wo, r) [r.z > 0] + (1 - F) G2(wo, t) [t.z < 0]] dh,
    r and t being wo reflected and refracted about h. No Jacobian, no sampler."""
    wo = direction(cos_wo)

    def lam(z):
        return 0.5 * (np.sqrt(1 + alpha * alpha * (1 - z * z) / (z * z)) - 1)

    def g(z):       # G2(wo, w) for w.z = z; zero on the horizon
        return np.where(np.abs(z) > 1e-9, 1 / (1 + lam(wo[2]) + lam(np.maximum(np.abs(z), 1e-9))), 0)

    def fn(h):
        c = h @ wo
        F = fresnel_vec(c, eta)
        r_z = 2 * c * h[:, 2] - wo[2]
        cos_t = np.sqrt(np.maximum(0, 1 - (1 - c * c) / eta ** 2))
        t_z = (c / eta - cos_t) * h[:, 2] - wo[2] / eta
        hz2 = h[:, 2] ** 2
        d = np.where(h[:, 2] > 0, alpha ** 2 / (np.pi * (hz2 * (alpha ** 2 - 1) + 1) ** 2), 0)
        return np.maximum(c, 0) * d / wo[2] * (F * g(r_z) * (r_z > 0) + (1 - F) * g(t_z) * (t_z < 0))

    return integrate(fn, log_spherical_domain((0, 0, 1), max_angle=0.5 * np.pi), res=res)


# E = R + eta^2 T at cos wo = (1, 0.5, 0.2), from albedo_by_normals at res (160, 128).
# 1 for a smooth interface, less for rough ones: single-scattering GGX loses the light
# that would scatter more than once (Cycles restores it from tables; this BSDF does not).
COS_E = (1.0, 0.5, 0.2)
ALBEDO = {
    (0.05, 1.5): (0.99972, 0.99815, 0.98120),
    (0.05, 1 / 1.5): (0.99735, 0.99141, 0.96003),
    (0.25, 1.5): (0.99204, 0.96077, 0.91502),
    (0.25, 1 / 1.5): (0.92924, 0.82708, 0.79355),
    (0.6, 1.5): (0.95539, 0.86151, 0.80854),
    (0.6, 1 / 1.5): (0.67647, 0.61700, 0.61882),
}


def split(wi, f, pdf, n):
    """(R, T, standard errors): reflected and refracted parts of the integral of
    f |cos| over the sphere, estimated from the samples' weights."""
    w = weights(wi, f, pdf)
    refr = wi[:, 2] < 0
    parts = [np.where(refr, 0, w), np.where(refr, w, 0)]
    return [p.mean() for p in parts], [p.std() / math.sqrt(n) for p in parts]


@pytest.mark.parametrize("radiance", [True, False])
@pytest.mark.parametrize("eta", [1.5, 1 / 1.5])
def test05_smooth_limit_splits_by_fresnel(eta, radiance, rng):
    """At alpha = ALPHA_MIN the interface is nearly smooth: it reflects R = F(cos wo)
    and refracts T = (1 - F) / eta^2 of the radiance (radiance=True: Veach's
    radiance scaling) or T = 1 - F (radiance=False: Cycles' and the adjoint
    convention); so R + eta^2 T = 1, or R + T = 1. Leaving glass (eta = 1 / 1.5) the
    radiance grows: T = 0.96 x 2.25 at normal incidence. Past the critical angle, R = 1."""
    n = 200_000
    for cos_wo in (1.0, 0.7, 0.4, 0.15):
        _, wi, f, pdf = draw(direction(cos_wo), ALPHA_MIN, eta, rng, n=n, radiance=radiance)
        (R, T), (sr, st) = split(wi, f, pdf, n)
        F = fresnel_ref(math.acos(cos_wo), eta)
        t = (1 - F) / eta ** 2 if radiance else 1 - F
        assert abs(R - F) < 4.5 * sr + 1e-3 and abs(T - t) < 4.5 * st + 1e-3, (cos_wo, R, F, T, t)


@pytest.mark.parametrize("alpha,eta", list(ALBEDO))
def test06_white_furnace(alpha, eta, rng):
    """With tint 1, R + eta^2 T of the radiance BSDF and R + T of the adjoint one both
    equal E of the table: at most 1, close to 1 for smooth-ish glass, and what
    the quadrature over microfacet normals (no sampler, no Jacobian) gives."""
    n = 200_000
    for cos_wo, expect in zip(COS_E, ALBEDO[alpha, eta]):
        assert albedo_by_normals(alpha, eta, cos_wo) == pytest.approx(expect, abs=3e-4)
        assert expect <= 1 and (alpha > 0.05 or expect > 0.95)
        for radiance in (True, False):
            _, wi, f, pdf = draw(direction(cos_wo), alpha, eta, rng, n=n, radiance=radiance)
            (R, T), _ = split(wi, f, pdf, n)
            w = weights(wi, f, pdf) * np.where((wi[:, 2] < 0) & radiance, eta * eta, 1)
            E, err = w.mean(), w.std() / math.sqrt(n)
            assert E == pytest.approx(R + (eta * eta if radiance else 1) * T)
            assert abs(E - expect) < 4.5 * err + 2e-4, (cos_wo, radiance, E, expect, err)
            assert E <= 1 + 4.5 * err


# --- 5. reciprocity -----------------------------------------------------------------------

@pytest.mark.parametrize("radiance", [True, False])
def test07_reciprocity(radiance, rng):
    """Swapping wo and wi swaps the media: the caller turns the frame over (z -> -z)
    and passes 1 / eta. Reflection is symmetric. Refraction with n_wo = 1, n_wi = eta:
    radiance f(wo, wi) / n_wo^2 = f(wi, wo) / n_wi^2 (Veach 1997, 5.2), i.e.
    f(wi, wo) = eta^2 f(wo, wi); the adjoint BSDF the other way round. Directions
    and eta in float64: near a critical angle 1 - F magnifies float32 rounding."""
    n = 20_000
    flip = np.array([1.0, 1.0, -1.0])

    def unit64(w):
        w = w.astype(np.float64)
        return w / np.sqrt((w * w).sum(axis=1, keepdims=True))

    for eta in (1.5, 1.33, 1 / 1.5):
        for alpha in (0.3, 0.05):
            wo, wi = unit64(unit(rng, n, +1)), unit64(unit(rng, n))
            a, t = col(alpha, n), rep((1, 1, 1), n)
            f, _ = glass.glass_eval(wo, wi, a, np.full(n, eta), t, radiance)
            refr = wi[:, 2] < 0
            wo2 = np.where(refr[:, None], wi * flip, wi)
            wi2 = np.where(refr[:, None], wo * flip, wo)
            f2, _ = glass.glass_eval(wo2, wi2, a, np.where(refr, 1 / eta, eta), t, radiance)
            assert np.array_equal(f[:, 0] > 0, f2[:, 0] > 0)
            assert (f[refr, 0] > 0).sum() > n / 20 and (f[~refr, 0] > 0).sum() > n / 4
            k = np.where(refr, eta * eta if radiance else 1 / (eta * eta), 1.0)
            assert np.allclose(f2[:, 0], k * f[:, 0], rtol=1e-5, atol=1e-8)


# --- 6. degenerate input ---------------------------------------------------------------------

def test08_degenerate_input(rng):
    up, down = np.float32([0, 0, 1]), np.float32([0, 0, -1])
    grazing = np.float32([1, 0, 0])
    wo = np.stack([grazing, grazing, -up, up, up, up, up, direction(0.5), direction(0.5)]).astype(np.float32)
    wi = np.stack([up, down, up, grazing, up, down, down, -direction(0.5), -direction(0.5)]).astype(np.float32)
    alpha = np.float32([0.3, 0.3, 0.3, 0.3, 0, 0, ALPHA_MIN, 1e-7, 0.5])
    eta = np.float32([1.5, 1.5, 1.5, 1.5, 1.5, 1.5, 1 / 1.5, 1.0, 1.0])
    f, pdf = glass.glass_eval(wo, wi, alpha, eta, rep((1, 1, 1), len(wo)))
    assert np.isfinite(f).all() and np.isfinite(pdf).all()
    # wo on the horizon or below, wi on the horizon: nothing.
    assert (f[:4] == 0).all() and (pdf[:4] == 0).all()
    # The peaks of the sharpest lobes: finite, D(h = z) = 1 / (pi ALPHA_MIN^2) ~ 3e5.
    assert (pdf[4:9] > 1e3).all() and (f[4:9] > 0).all()
    # Index-matched (eta = 1), whatever the roughness: -wo is the peak of a lobe at ALPHA_MIN.
    d_peak = 1 / (math.pi * ALPHA_MIN ** 2)
    assert pdf[7] == pdf[8] and pdf[7] == pytest.approx(d_peak / (4 * 0.5), rel=1e-2)

    # Sampling: random directions (a third below the horizon), alpha in [0, 1] and eta
    # around 1, including exactly 1. Everything finite, lost samples zero.
    n = 100_000
    wo = unit(rng, n)
    wo[: n // 3, 2] = np.abs(wo[: n // 3, 2])
    wo[:100, 2] = 0
    alpha = rng.random(n, dtype=np.float32) ** 2
    eta = rng.choice(np.float32([1.0, 1.0005, 1 / 1.0005, 1.5, 1 / 1.5, 2.5, 0.4]), n)
    wi, f, pdf = glass.glass_sample(wo, alpha, eta, rep((1, 1, 1), n), rng.random(n, dtype=np.float32),
                                    rng.random((n, 2), dtype=np.float32))
    assert np.isfinite(wi).all() and np.isfinite(f).all() and np.isfinite(pdf).all()
    assert (f >= 0).all() and (pdf >= 0).all() and (f[pdf == 0] == 0).all()
    assert (pdf[wo[:, 2] <= 0] == 0).all() and (pdf > 0).sum() > n / 4
    f_e, pdf_e = glass.glass_eval(wo, wi, alpha, eta, rep((1, 1, 1), n))
    assert np.isfinite(f_e).all() and np.isfinite(pdf_e).all()

    # eta = 1 samples go straight through with weight 1 and no reflection, rough or not.
    for alpha in (0.0, 0.5):
        wo, wi, f, pdf = draw(direction(0.5), alpha, 1.0, rng, n=20_000, tint=(0.9, 0.5, 0.2))
        assert (pdf > 0).all() and (wi[:, 2] < 0).all()
        miss = np.linalg.norm(wi + wo, axis=1)          # GGX at ALPHA_MIN: 1e-3 rad, long tails
        assert np.median(miss) < 3e-3 and np.quantile(miss, 0.99) < 0.03
        assert np.abs(np.median(wi + wo, axis=0)).max() < 1e-4
        assert np.allclose(f * np.abs(wi[:, 2:3]) / pdf[:, None], [0.9, 0.5, 0.2], rtol=1e-4)
