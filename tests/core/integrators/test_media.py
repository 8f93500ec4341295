"""core/integrators/media.py without Blender: the world's medium
(Scene.world_volume) along rays, alone and with an object's medium."""

import numpy as np

from restir_gi.core.integrators.media import media_of
from support.scenes import cornell_box

SIGMA_A = (0.2, 0.4, 0.8)
SIGMA_S = (0.1, 0.1, 0.1)
EMISSION = (0.3, 0.2, 0.1)


def _world_scene(**volume):
    scene = cornell_box("area", 8, 8)
    scene.world_volume = {"sigma_a": SIGMA_A, "sigma_s": SIGMA_S, "emission": EMISSION, "g": 0.0, **volume}
    return scene


def test01_finite_and_infinite_segments():
    """Transmittance exp(-sigma_t L) over a finite segment and 0 to infinity;
    the emission arriving from an infinite length is emission / sigma_t."""
    scene = _world_scene()
    media = media_of(scene, 1e-4)
    assert media is not None
    o = np.zeros((3, 3), np.float32)
    d = np.tile(np.float32([0, 0, 1]), (3, 1))
    iv = media.along(o, d, np.array([1.0, 2.5, np.inf]))
    st = np.add(SIGMA_A, SIGMA_S)
    tr = iv.transmittance()
    np.testing.assert_allclose(tr[0], np.exp(-st), rtol=1e-5)
    np.testing.assert_allclose(tr[1], np.exp(-2.5 * st), rtol=1e-5)
    np.testing.assert_allclose(tr[2], 0.0)
    np.testing.assert_allclose(iv.emission()[2], np.divide(EMISSION, st), rtol=1e-5)
    assert np.isfinite(iv.emission()).all()


def test02_zero_density_is_no_medium():
    """A world volume of density zero makes no media at all (the ReSTIR modes
    then stay ReSTIR)."""
    scene = _world_scene(sigma_a=(0, 0, 0), sigma_s=(0, 0, 0), emission=(0, 0, 0))
    assert media_of(scene, 1e-4) is None


def test03_free_flights_scatter_everywhere_in_an_infinite_medium():
    """No ray escapes an infinite scattering medium: every free flight ends
    at a scattering point, at the mean distance 1 / sigma_t."""
    scene = _world_scene(sigma_a=(0, 0, 0), sigma_s=(0.5, 0.5, 0.5), emission=(0, 0, 0))
    media = media_of(scene, 1e-4)
    n = 100000
    rng = np.random.default_rng(3)
    o = np.zeros((n, 3), np.float32)
    d = np.tile(np.float32([1, 0, 0]), (n, 1))
    scat, t, w, ss, g = media.along(o, d, np.full(n, np.inf)).sample(rng.random(n), rng.random(n))
    assert scat.all()
    se = t.std() / np.sqrt(n)
    assert abs(t.mean() - 2.0) < 4 * se
    np.testing.assert_allclose(w, 1.0, rtol=1e-5)       # sigma_s T / pdf, scattering only
