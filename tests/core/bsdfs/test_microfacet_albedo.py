"""The GGX albedo tables (core/bsdfs/microfacet_albedo.py) against quadrature
of the lobe itself: E = f0 A + (f90 - x) B + x R for a lobe whose share x
rises along the exact dielectric Fresnel curve, and the curve's
hemispherical average against the exact Fresnel's."""

import numpy as np
import pytest

from support.chi2 import integrate, spherical_domain
from restir_gi.core.bsdfs import bsdf
from restir_gi.core.bsdfs.fresnel import fresnel_dielectric
from restir_gi.core.bsdfs.microfacet_albedo import albedo_terms, rise_average

HEMISPHERE = spherical_domain(cos_range=(0.0, 1.0))


def lobe_albedo(rough, cos_wo, f0, f90, exact, eta):
    """Integral of f cos of a single-scattering GGX lobe (no at_view: nothing put back)."""
    wo = np.float32([np.sqrt(1 - cos_wo ** 2), 0.0, cos_wo])

    def fn(w):
        w = np.asarray(w, np.float32)
        n = len(w)
        p = bsdf.lobe_params(np.zeros((n, 3), np.float32), np.full((n, 3), f0, np.float32),
                             np.full(n, rough, np.float32), np.full((n, 3), f90, np.float32),
                             exact=(np.full((n, 3), exact, np.float32), np.full(n, eta, np.float32)))
        p.p_spec[:] = 1.0       # evaluated even where f0 = 0 (lobe_params would pick it never)
        f = bsdf.evaluate(p, np.broadcast_to(wo, (n, 3)).copy(), w)
        return f[:, 0] * np.maximum(w[:, 2], 0.0)
    return integrate(fn, HEMISPHERE, res=(48, 48))


@pytest.mark.parametrize("rough", [0.3, 0.7])
@pytest.mark.parametrize("eta", [1.45, 2.2, 1 / 1.33])
def test01_tables_match_the_lobe(rough, eta):
    for cos_wo in (0.9, 0.5, 0.2):
        a, b, r = (float(v[0]) for v in albedo_terms(np.float32([rough]), np.float32([cos_wo]),
                                                      np.float32([eta])))
        # Schlick's lobe and the exact curve's rise, each alone.
        assert a + b == pytest.approx(lobe_albedo(rough, cos_wo, 1.0, 1.0, 0.0, eta), rel=0.02, abs=2e-3)
        assert b == pytest.approx(lobe_albedo(rough, cos_wo, 0.0, 1.0, 0.0, eta), rel=0.03, abs=2e-3)
        if eta > 1:      # the table takes an IOR and its inverse alike (as Cycles'); the lobe does not
            assert r == pytest.approx(lobe_albedo(rough, cos_wo, 0.0, 1.0, 1.0, eta), rel=0.03, abs=2e-3)


def test02_rise_average_is_the_exact_fresnel_average():
    mu = (np.arange(20000) + 0.5) / 20000
    for eta in (1.1, 1.45, 1.5, 2.4, 4.0):
        f = fresnel_dielectric(mu.astype(np.float32), np.full(len(mu), eta, np.float32))[0]
        f_avg = 2 * np.mean(f * mu)
        r0 = ((eta - 1) / (eta + 1)) ** 2
        got = r0 + (1 - r0) * float(rise_average(np.float32([eta]))[0])
        assert got == pytest.approx(f_avg, rel=0.01), eta
    # At IOR 1.45, Schlick's curve with a white f90 averages 0.0797, the exact one 0.0843.
    r0 = (0.45 / 2.45) ** 2
    assert r0 + (1 - r0) * float(rise_average(np.float32([1.45]))[0]) == pytest.approx(0.0843, abs=5e-4)
