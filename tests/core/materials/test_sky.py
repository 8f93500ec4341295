"""Blender's Sky Texture models (core/materials/shader/sky.py, sky_scattering.py,
sky_analytic.py) against values derived here another way: the sun's
transmittance by fine quadrature, an optically thin atmosphere's single
scattering in closed form, the sun disc's irradiance from its limb darkening,
Preetham's zenith from the paper's formulas, Hosek-Wilkie's zenith from its
table; and the environment finding the disc (core/lights/environment.py): NEE alone
gives the irradiance of sky and sun without fireflies."""

import copy

import numpy as np
import pytest

from restir_gi.core.lights.environment import Environment
from restir_gi.core.materials.shader import sky_scattering as scattering
from restir_gi.core.materials.shader.nodes_spectrum import XYZ_TO_REC709
from restir_gi.core.materials.shader.sky import normalised_sun, sky_model

trapezoid = getattr(np, "trapezoid", None) or np.trapz     # numpy 2 renamed it, then removed trapz

# Multiple scattering's spectral constants (630, 560, 490, 430 nm) as Blender publishes them.
SUN = np.array([1.679, 1.828, 1.986, 1.307])
MOLECULAR = np.array([6.605e-3, 1.067e-2, 1.842e-2, 3.156e-2])
TO_XYZ = np.array([[53.386917738564668, 22.981337506691025, 0.0],
                   [43.904844466369358, 71.347795700053394, 0.102506867965741],
                   [1.6137278251608962, 18.422960591455485, 31.742921188390806],
                   [20.762668673810577, 2.3614213523314369, 110.48009643252140]])


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def sky(sky_type="MULTIPLE_SCATTERING", elevation=30.0, **props):
    return sky_model({"sky_type": sky_type, "sun_elevation": np.radians(elevation), **props})


def test01_transmittance_matches_quadrature():
    """A sun at the zenith through air alone (no aerosols, no ozone): its
    radiance is the top-of-atmosphere spectrum times exp(-tau), tau the
    molecular optical depth from the viewer's altitude up, integrated here on
    a fine grid."""
    altitude = 2000.0
    h = np.linspace(altitude / 1000, 100.0, 200_001)
    density = np.exp(-0.07771971 * h ** 1.16364243)
    tau = MOLECULAR * trapezoid(density, h)
    half = 0.01 / 2
    solid = 2 * np.pi * (1 - np.cos(half))
    want = (SUN * np.exp(-tau) / solid) @ TO_XYZ
    got = scattering.multiple_scattering_sun(np.pi / 2 - half, 0.01, altitude, 1.0, 0.0, 0.0)
    np.testing.assert_allclose(got[0], want, rtol=2e-3)
    clear = scattering.multiple_scattering_sun(np.pi / 2 - half, 0.01, altitude, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(clear[0], (SUN / solid) @ TO_XYZ, rtol=1e-6)


def test02_thin_single_scattering_closed_form():
    """In a thin atmosphere (air at 1e-3 of its density, no aerosols or ozone)
    light scatters once without loss: a ray near the zenith gathers
    beta(lambda) H (1 - e^(-60 km / H)) / sin(latitude) times the Rayleigh
    phase function times the sun's spectrum, H = 8 km (a flat atmosphere is
    close enough near the zenith)."""
    elevation = np.radians(40.0)
    table = scattering.single_scattering_table(elevation, 1.0, 1e-3, 0.0, 0.0)
    row, col = 250, 128
    lat = np.pi / 2 * (row / 128 - 1) ** 2
    lon = 2 * np.pi * col / 512 - np.pi
    d = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    mu = d @ np.array([np.cos(elevation), 0.0, np.sin(elevation)])
    H = 8000.0
    column = 1e-3 * H * (1 - np.exp(-60e3 / H)) / np.sin(lat)
    spectrum = scattering._RAY * column * (3 / (16 * np.pi)) * (1 + mu * mu) * scattering._IRR
    want = spectrum @ scattering._CMF * 20.0
    np.testing.assert_allclose(table[row, col], want, rtol=0.01)
    assert (table[:129] == 0).all()          # the ground is black in the table


@pytest.mark.slow
@pytest.mark.parametrize("sky_type", ["MULTIPLE_SCATTERING", "SINGLE_SCATTERING"])
def test03_sun_disc_irradiance(sky_type):
    """The disc's irradiance at normal incidence is its centre radiance times
    its solid angle times the mean of the limb darkening 1 - 0.6 (1 - cos),
    which is 1 - 0.6 / 3 = 0.8 (the linear blend from bottom to top averages
    out); integrated here over a polar grid about the sun, the sky beneath
    taken off."""
    model = sky(sky_type, 30.0, sun_rotation=np.radians(50.0), sun_size=np.radians(2.0))
    no_disc = copy.copy(model)
    no_disc.sun_disc = False
    s, half = model.sun_direction, model.diameter / 2
    t = unit(np.cross(s, [0, 0, 1]))
    b = np.cross(s, t)
    k = 400
    r = (np.arange(k) + 0.5) / k * half * 1.001
    phi = (np.arange(2 * k) + 0.5) / (2 * k) * 2 * np.pi
    R, P = np.meshgrid(r, phi, indexing="ij")
    R, P = R.ravel(), P.ravel()
    d = np.cos(R)[:, None] * s + (np.sin(R) * np.cos(P))[:, None] * t + (np.sin(R) * np.sin(P))[:, None] * b
    area = np.sin(R) * (r[1] - r[0]) * (phi[1] - phi[0])
    disc = (model.radiance(d).astype(np.float64) - no_disc.radiance(d)) * area[:, None]
    solid = 2 * np.pi * (1 - np.cos(half))
    centre = np.maximum(model.sun_xyz.mean(axis=0) @ XYZ_TO_REC709.T, 0)
    np.testing.assert_allclose(disc.sum(axis=0), centre * solid * 0.8, rtol=3e-3)


def test04_sun_position_and_wrapping():
    """The sun sits at (cos e sin r, cos e cos r, sin e) for elevation e and
    rotation r (rotation 0 faces +Y, 90 degrees +X), and is drawn there; an
    elevation past the zenith is the sun turned around."""
    e, r = np.radians(30.0), np.radians(90.0)
    model = sky("MULTIPLE_SCATTERING", 30.0, sun_rotation=r)
    want = np.array([np.cos(e) * np.sin(r), np.cos(e) * np.cos(r), np.sin(e)])
    np.testing.assert_allclose(model.sun_direction, want, atol=1e-6)
    off = unit(want + [0, 0, 0.05])
    sun, beside = model.radiance(np.array([want, off]))
    assert sun.min() > 1000 * beside.max() > 0
    assert model.has_sun
    a = normalised_sun(np.radians(100.0), 0.0)
    b = normalised_sun(np.radians(80.0), np.pi)
    np.testing.assert_allclose(a, b, atol=1e-6)


def test05_preetham_zenith_from_the_paper():
    """At the zenith Perez's distribution divides out: Preetham's zenith
    luminance (kcd/m2, times Cycles' 0.06) and chromaticity, from the paper's
    formulas in turbidity T and the sun's zenith angle."""
    T, ts = 3.0, np.radians(50.0)
    d_sun = [np.sin(ts) * 0.6, np.sin(ts) * 0.8, np.cos(ts)]
    model = sky("PREETHAM", sun_direction=tuple(d_sun), turbidity=T)
    chi = (4 / 9 - T / 120) * (np.pi - 2 * ts)
    Y = ((4.0453 * T - 4.9710) * np.tan(chi) - 0.2155 * T + 2.4192) * 0.06
    th = np.array([ts ** 3, ts ** 2, ts, 1.0])
    x = np.array([T * T, T, 1]) @ np.array([[0.00166, -0.00375, 0.00209, 0],
                                            [-0.02903, 0.06377, -0.03202, 0.00394],
                                            [0.11693, -0.21196, 0.06052, 0.25886]]) @ th
    y = np.array([T * T, T, 1]) @ np.array([[0.00275, -0.00610, 0.00317, 0],
                                            [-0.04214, 0.08970, -0.04153, 0.00516],
                                            [0.15346, -0.26756, 0.06670, 0.26688]]) @ th
    xyz = np.array([x / y * Y, Y, (1 - x - y) / y * Y])
    got = model.radiance(np.array([[0.0, 0.0, 1.0]]))[0]
    np.testing.assert_allclose(got, np.maximum(XYZ_TO_REC709 @ xyz, 0), rtol=1e-4)


def test06_hosek_wilkie_zenith_from_the_table():
    """A sun at the zenith, turbidity 4, albedo 0: the table's last control
    point of row (albedo 0, turbidity 4) alone, and at the zenith (theta =
    gamma = 0) the distribution is (1 + A e^(B / 1.01)) (C + D + F + G (2 /
    (1 - H)^3) + I); times the channel's radiance and 2 pi / 683."""
    from restir_gi.core.materials.shader.sky_hosek_data import CONFIGS, RADIANCES
    model = sky("HOSEK_WILKIE", sun_direction=(0.0, 0.0, 1.0), turbidity=4.0, ground_albedo=0.0)
    c = CONFIGS[:, 0, 3, 5]
    f = (1 + c[:, 0] * np.exp(c[:, 1] / 1.01)) * (c[:, 2] + c[:, 3] + c[:, 5] + c[:, 6] * 2 / (1 - c[:, 8]) ** 3
                                                  + c[:, 7])
    xyz = f * RADIANCES[:, 0, 3, 5]
    got = model.radiance(np.array([[0.0, 0.0, 1.0]]))[0]
    np.testing.assert_allclose(got, np.maximum(XYZ_TO_REC709 @ xyz, 0) * 2 * np.pi / 683, rtol=1e-4)


@pytest.mark.parametrize("sky_type", ["MULTIPLE_SCATTERING", "SINGLE_SCATTERING", "PREETHAM", "HOSEK_WILKIE"])
def test07_finite_everywhere(sky_type):
    """Every direction, the poles, the sun's centre and degenerate vectors give
    finite, non-negative radiance."""
    model = sky(sky_type, 30.0)
    rng = np.random.default_rng(3)
    d = np.concatenate([rng.normal(size=(2000, 3)), [[0, 0, 1], [0, 0, -1], [0, 0, 0], [1e-30, 0, 0]]])
    if getattr(model, "has_sun", False):
        d = np.concatenate([d, [model.sun_direction]])
    rgb = model.radiance(d)
    assert rgb.shape == (len(d), 3) and rgb.dtype == np.float32
    assert np.isfinite(rgb).all() and (rgb >= 0).all()


def test08_environment_samples_the_sun(rng):
    """A sunny sky as the world: NEE alone (the environment's samples over
    their density) gives the irradiance of an upward surface, sky by
    quadrature plus the disc's 0.8 x centre x solid angle x cos, and no
    sample carries more than a small multiple of the mean: the disc, far
    smaller than a texel, is found by its own sampling, not by chance."""
    model = sky("MULTIPLE_SCATTERING", 30.0, sun_rotation=np.radians(20.0))
    no_disc = copy.copy(model)
    no_disc.sun_disc = False
    env = Environment(model.radiance, resolution=256, sun=(model.sun_direction, model.diameter / 2))
    assert 0.5 < env.sun_pmf < 0.95
    k = 600
    c = (np.arange(k) + 0.5) / k
    phi = (np.arange(2 * k) + 0.5) / (2 * k) * 2 * np.pi
    C, F = np.meshgrid(c, phi, indexing="ij")
    s = np.sqrt(1 - C * C).ravel()
    d = np.stack([s * np.cos(F.ravel()), s * np.sin(F.ravel()), C.ravel()], axis=1)
    sky_e = (no_disc.radiance(d).astype(np.float64) * C.ravel()[:, None]).sum(axis=0) * (np.pi / k / k)
    half = model.diameter / 2
    centre = np.maximum(model.sun_xyz.mean(axis=0) @ XYZ_TO_REC709.T, 0)
    sun_e = centre * 0.8 * 2 * np.pi * (1 - np.cos(half)) * model.sun_direction[2]
    want = sky_e + sun_e
    n = 200_000
    wi, pdf, rad = env.sample(rng.random((n, 2)))
    cos = np.maximum(wi[:, 2].astype(np.float64), 0)
    f = rad * (cos / np.where(pdf > 0, pdf, 1))[:, None] * (pdf > 0)[:, None]
    est, err = f.mean(axis=0), f.std(axis=0) / np.sqrt(n)
    assert (np.abs(est - want) < 4 * err + 2e-3 * want).all(), (est, want, err)
    assert (err < 0.01 * want).all()
    lum = f.mean(axis=1)
    assert lum.max() < 12 * lum.mean()
    np.testing.assert_allclose(env.pdf(wi[:2000]), pdf[:2000], rtol=1e-4)
