"""Fresnel terms (core/bsdfs/fresnel.py): the exact dielectric reflectance
against the angle forms, and the exact curve's rise that Cycles' Principled
BSDF remaps to its f0."""

import math

import numpy as np
import pytest

from support.optics import fresnel_ref
from restir_gi.core.bsdfs import fresnel
from restir_gi.core.bsdfs.fresnel import dielectric_rise, ior_from_f0


def col(x, n):
    return np.full(n, x, np.float32)


# --- 1. Fresnel ----------------------------------------------------------------------

def test01_fresnel_dielectric():
    F, cos_t = fresnel.fresnel_dielectric(np.float32([1.0, 1.0]), np.float32([1.5, 1 / 1.5]))
    assert F.dtype == np.float32 and np.allclose(F, 0.04, atol=1e-7)     # ((eta - 1) / (eta + 1))^2
    assert np.allclose(cos_t, 1.0)
    # Brewster's angle, tan = eta: R_p = 0, so F = R_s / 2 = ((eta^2 - 1) / (eta^2 + 1))^2 / 2.
    eta = 1.5
    F, _ = fresnel.fresnel_dielectric(np.float32([math.cos(math.atan(eta))]), np.float32([eta]))
    assert F[0] == pytest.approx(((eta ** 2 - 1) / (eta ** 2 + 1)) ** 2 / 2, rel=1e-5)
    # Textbook value: glass at 45 degrees reflects 5.0% (R_s 9.2%, R_p 0.85%).
    F, cos_t = fresnel.fresnel_dielectric(np.float32([math.sqrt(0.5)]), np.float32([1.5]))
    assert F[0] == pytest.approx(0.0503, abs=1e-4)
    assert cos_t[0] == pytest.approx(math.sqrt(1 - 0.5 / 2.25), rel=1e-6)
    # Against the angle-form reference, both ways across the interface.
    theta = np.linspace(0, 0.5 * math.pi - 1e-3, 200)
    for eta in (1.5, 1 / 1.5, 1.33, 2.4, 1 / 2.4):
        F, cos_t = fresnel.fresnel_dielectric(np.cos(theta).astype(np.float32), col(eta, len(theta)))
        assert np.allclose(F, [fresnel_ref(t, eta) for t in theta], rtol=1e-4, atol=2e-6)
        assert ((0 <= F) & (F <= 1)).all()
        # Reflectance is the same from either side (Stokes): F(cos_i, eta) = F(cos_t, 1 / eta).
        ok = F < 1
        back, _ = fresnel.fresnel_dielectric(cos_t[ok], col(1 / eta, ok.sum()))
        assert np.allclose(back, F[ok], rtol=1e-3, atol=1e-5)      # float32 cos_t near grazing
    # Total internal reflection beyond the critical angle, sin = eta, and not before.
    eta = 1 / 1.5
    c = math.sqrt(1 - eta * eta)
    F, cos_t = fresnel.fresnel_dielectric(np.float32([c - 1e-3, 0.3, 0.0, c + 1e-3]), col(eta, 4))
    assert (F[:3] == 1).all() and (cos_t[:3] == 0).all()
    assert 0.5 < F[3] < 1 and cos_t[3] > 0
    # Index-matched: no reflection, no bending.
    F, cos_t = fresnel.fresnel_dielectric(np.float32([1.0, 0.5, 0.01]), col(1.0, 3))
    assert np.allclose(F, 0, atol=1e-12) and np.allclose(cos_t, [1.0, 0.5, 0.01])




# --- 2. the exact curve's rise (Cycles' Principled dielectric layer) -----------------

@pytest.mark.parametrize("eta", [1.45, 1.5, 2.4, 1 / 1.5, 1 / 1.33])
def test02_rise_is_the_exact_curve_remapped_to_its_normal_reflectance(eta):
    theta = np.linspace(0, 0.5 * math.pi, 181)
    cos = np.cos(theta).astype(np.float32)
    rise = dielectric_rise(cos, col(eta, len(cos)))
    r0 = ((eta - 1) / (eta + 1)) ** 2
    ref = [(fresnel_ref(t, eta) - r0) / (1 - r0) for t in theta]
    assert rise.dtype == np.float32
    assert np.allclose(rise, ref, atol=5e-4)
    assert rise[0] == pytest.approx(0.0, abs=1e-6) and rise[-1] == pytest.approx(1.0, abs=1e-6)
    assert (np.diff(rise) >= -1e-6).all()                  # it only rises toward grazing
    if eta < 1:
        # An IOR below one reflects totally beyond the critical angle.
        assert (rise[np.sin(theta) > eta + 1e-3] == 1).all()


def test03_rise_at_an_ior_of_one_and_at_the_largest():
    cos = np.float32([1.0, 0.5, 0.05, 0.0])
    assert np.allclose(dielectric_rise(cos[:3], col(1.0, 3)), 0.0)
    big = dielectric_rise(cos, col(1e9, 4))
    assert np.isfinite(big).all() and ((0 <= big) & (big <= 1)).all()


def test04_ior_from_f0_inverts_the_normal_reflectance():
    f0 = np.float32([0.0, 0.02, 0.04, 0.25, 0.9])
    eta = ior_from_f0(f0)
    assert np.allclose(((eta - 1) / (eta + 1)) ** 2, f0, atol=1e-6)
    assert np.allclose(ior_from_f0(f0, True), 1 / eta)
    # As Cycles, at most the IOR of a normal reflectance of 0.99.
    assert ior_from_f0(np.float32([1.0]))[0] == pytest.approx(ior_from_f0(np.float32([0.99]))[0])
