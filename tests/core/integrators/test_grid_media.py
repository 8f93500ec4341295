"""Voxel grids as heterogeneous media (core/integrators/grid_media.py) through
Media (core/integrators/media.py): transmittance against the closed form of
the trilinear density, free flights against it, grids joined with the
homogeneous media's intervals, and bad grids."""

from types import SimpleNamespace

import numpy as np

from restir_gi.core.integrators.grid_media import GridMedium, PreparedGrid
from restir_gi.core.integrators.media import C, Media, coefficients

SIGMA_A = (0.1, 0.2, 0.3)
SIGMA_S = (0.5, 0.5, 0.5)


def _scene():
    return SimpleNamespace(material_ids=np.zeros(0, np.int32), shaders=[], object_ids=None,
                           face_normals=np.zeros((0, 3), np.float32), vertices=np.zeros((0, 3), np.float32),
                           triangles=np.zeros((0, 3), np.int32))


def _box_scene(lo, hi, volume):
    """A closed box of 12 outward-facing triangles whose material 0 holds ``volume``."""
    v = np.array([(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], np.float32)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = np.array([t for a, b, c, e in quads for t in ((a, b, c), (a, c, e))], np.int32)
    e1, e2 = v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]]
    nrm = np.cross(e1, e2)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    centre = v[tris].mean(axis=1) - (np.asarray(lo) + np.asarray(hi)) / 2
    nrm *= np.sign((nrm * centre).sum(axis=1))[:, None]         # outward
    scene = SimpleNamespace(material_ids=np.zeros(len(tris), np.int32), shaders=[None], object_ids=None,
                            face_normals=nrm.astype(np.float32), vertices=v, triangles=tris)
    return scene, {0: volume}


def _grid(dens, lo=-1.0, hi=1.0, emission=(0.0, 0.0, 0.0)):
    """A grid whose voxel centres span [lo, hi] on each axis."""
    n = dens.shape[0]
    voxel = (hi - lo) / (n - 1)
    to_index = np.eye(4)
    to_index[:3, :3] /= voxel
    to_index[:3, 3] = -lo / voxel
    const = coefficients({"emission": emission}) if any(emission) else np.zeros(C, np.float32)
    return GridMedium(np.asarray(dens, np.float32), to_index,
                      coefficients({"sigma_a": SIGMA_A, "sigma_s": SIGMA_S, "g": 0.3}), const)


def _media(*grids, volumes=None, scene=None):
    return Media(scene or _scene(), volumes or {}, 1e-4, None, list(grids))


def _rays(o, n=1):
    o = np.tile(np.asarray(o, np.float32), (n, 1))
    d = np.tile(np.asarray([1.0, 0.0, 0.0], np.float32), (n, 1))
    return o, d


def test01_constant_grid_transmittance_is_the_closed_form():
    """A constant density: full density between the first and last voxel
    centres, a linear fall to zero over one voxel past each (trilinear):
    optical depth density x (length between centres + one voxel)."""
    n, dens = 16, 2.0
    media = _media(_grid(np.full((n, n, n), dens)))
    o, d = _rays((-5.0, 0.1, -0.2))
    tr = media.along(o, d, np.array([np.inf])).transmittance()[0]
    sigma_t = np.array(SIGMA_A) + np.array(SIGMA_S)
    length = 2.0 + 2.0 / (n - 1)
    np.testing.assert_allclose(tr, np.exp(-dens * sigma_t * length), rtol=1e-4)
    # A ray that misses the box and one that ends before it see none.
    o2, d2 = _rays((-5.0, 5.0, 0.0))
    assert np.allclose(media.along(o2, d2, np.array([np.inf])).transmittance(), 1.0)
    assert np.allclose(media.along(o, d, np.array([3.0])).transmittance(), 1.0)


def test02_linear_ramp_against_its_integral():
    """Density rising linearly along x: the midpoint rule integrates it
    exactly, so the transmittance is exp(-sigma_t x integral)."""
    n = 33
    x = np.linspace(0.0, 1.0, n)
    dens = np.broadcast_to(x[:, None, None], (n, n, n)).copy()
    media = _media(_grid(dens))
    o, d = _rays((-3.0, 0.0, 0.0))
    tr = media.along(o, d, np.array([np.inf])).transmittance()[0]
    voxel = 2.0 / (n - 1)
    # Inside: integral of x over [0, 1] along 2 world units = 1; past the
    # last centre density falls from 1 to 0 over one voxel: + voxel / 2.
    integral = 1.0 + voxel / 2
    np.testing.assert_allclose(tr, np.exp(-integral * (np.array(SIGMA_A) + np.array(SIGMA_S))), rtol=2e-3)


def test03_free_flights_match_the_transmittance():
    """Sampled distances: the weights of passing rays average to the
    transmittance, those of scattered ones to the scattered share
    integral T sigma_s, which with sigma_s / sigma_t constant is
    sigma_s / sigma_t (1 - T); scattering points lie in the box."""
    n, rays = 12, 60000
    rng = np.random.default_rng(3)
    dens = rng.random((n, n, n)).astype(np.float32) * 2.0
    media = _media(_grid(dens))
    o, d = _rays((-4.0, 0.05, 0.1), rays)
    seg = media.along(o, d, np.full(rays, np.inf))
    tr = seg.transmittance()[0]
    scat, t, w, ss, g = seg.sample(rng.random(rays), rng.random(rays))
    sigma_t = np.array(SIGMA_A) + np.array(SIGMA_S)
    np.testing.assert_allclose((w * ~scat[:, None]).mean(axis=0), tr, rtol=0.03)
    np.testing.assert_allclose((w * scat[:, None]).mean(axis=0), np.array(SIGMA_S) / sigma_t * (1 - tr), rtol=0.03)
    x = o[scat, 0] + t[scat]
    assert x.min() > -1.0 - 2.0 / (n - 1) and x.max() < 1.0 + 2.0 / (n - 1)
    np.testing.assert_allclose(g[scat], 0.3, atol=1e-5)


def test04_grid_joins_a_homogeneous_box_and_another_grid():
    """Optical depths add: a grid inside a box of homogeneous medium, and
    two overlapping grids, give the product of their transmittances."""
    n = 10
    grid = _grid(np.full((n, n, n), 0.7))
    scene, volumes = _box_scene((-2, -2, -2), (2, 2, 2), {"sigma_a": (0.2, 0.2, 0.2), "sigma_s": (0.0, 0.0, 0.0)})
    o, d = _rays((-5.0, 0.0, 0.0))
    end = np.array([np.inf])
    t_grid = _media(grid).along(o, d, end).transmittance()[0]
    t_box = Media(scene, volumes, 1e-4).along(o, d, end).transmittance()[0]
    t_both = _media(grid, volumes=volumes, scene=scene).along(o, d, end).transmittance()[0]
    np.testing.assert_allclose(t_both, t_grid * t_box, rtol=1e-4)
    assert t_box[0] < 0.5 and t_grid[0] < 0.5          # each matters
    t_two = _media(grid, _grid(np.full((n, n, n), 0.7), -0.5, 1.5)).along(o, d, end).transmittance()[0]
    t_shift = _media(_grid(np.full((n, n, n), 0.7), -0.5, 1.5)).along(o, d, end).transmittance()[0]
    np.testing.assert_allclose(t_two, t_grid * t_shift, rtol=1e-4)


def test05_emission_fills_the_box():
    """A grid's constant emission: radiance emission x length through the
    box (voxel cells grown by half a voxel) where nothing absorbs."""
    n = 9
    g = _grid(np.zeros((n, n, n)), emission=(1.0, 0.5, 0.25))
    media = _media(g)
    o, d = _rays((-5.0, 0.0, 0.0))
    em = media.along(o, d, np.array([np.inf])).emission()[0]
    voxel = 2.0 / (n - 1)
    np.testing.assert_allclose(em, np.array([1.0, 0.5, 0.25]) * (2.0 + 2 * voxel), rtol=1e-4)


def test06_bad_grids_are_no_medium():
    """NaN and negative voxels read as zero, an empty or singular grid is
    no medium at all; nothing returns NaN."""
    n = 6
    dens = np.full((n, n, n), np.nan, np.float32)
    dens[0, 0, 0] = -3.0
    assert PreparedGrid(_grid(dens)).empty
    assert PreparedGrid(_grid(np.zeros((0, 0, 0)))).empty
    bad = _grid(np.ones((n, n, n)))
    bad.to_index = np.zeros((4, 4))
    assert PreparedGrid(bad).empty
    mixed = np.ones((n, n, n), np.float32)
    mixed[2, 2, 2] = np.inf
    media = _media(_grid(mixed))
    o, d = _rays((-5.0, 0.0, 0.0), 4)
    seg = media.along(o, d, np.full(4, np.inf))
    rng = np.random.default_rng(0)
    scat, t, w, ss, g = seg.sample(rng.random(4), rng.random(4))
    for out in (seg.transmittance(), seg.emission(), w, ss, g, t[scat]):
        assert np.isfinite(np.asarray(out, np.float64)).all()


def test07_a_temperature_grid_glows_as_a_blackbody():
    """A temperature grid (no density, nothing else emits): the rays through
    it gather the blackbody emission of its temperature over its length,
    between the span of full temperature and that span plus a voxel."""
    from restir_gi.core.integrators.grid_media import blackbody_emission
    n = 11
    hot = _grid(np.ones((n, n, n)))
    hot.blackbody = (1500.0, 1.0, (1.0, 0.5, 0.25))
    media = _media(hot)
    o, d = _rays((-5.0, 0.0, 0.0))
    em = media.along(o, d, np.array([np.inf])).emission()[0]
    voxel = 2.0 / (n - 1)
    per_length = blackbody_emission(1500.0, 1.0) * np.array([1.0, 0.5, 0.25])
    assert per_length[0] > 0.1
    assert (em >= per_length * 2.0 - 1e-6).all() and (em <= per_length * (2.0 + voxel) + 1e-6).all()
    assert np.allclose(media.along(o, d, np.array([np.inf])).transmittance(), 1.0)    # it absorbs nothing


def test08_a_colour_grid_tints_scattering_and_absorption():
    """A Principled Volume's colour grid: the scattering colour is Color x
    the grid's, absorption (1 - that) x (1 - sqrt(Absorption Color)), both
    times the density (a segment inside the grid, clear of the fall to zero
    past its last voxels, where density and colour both fall)."""
    n, dens, factor = 8, 1.5, 2.0
    base, absorb = np.array([0.8, 0.6, 0.4]), np.array([0.5, 0.7, 0.9])
    o, d = _rays((-0.5, 0.0, 0.0))
    length = 1.0
    for colour in ((1.0, 1.0, 1.0), (0.5, 1.0, 0.25)):
        g = _grid(np.full((n, n, n), dens))
        g.color = (np.broadcast_to(np.float32(colour), (n, n, n, 3)).copy(), base, factor, absorb, 0.2)
        tr = _media(g).along(o, d, np.array([length])).transmittance()[0]
        scatter = base * np.array(colour)
        sigma_t = (scatter + (1 - scatter) * absorb) * factor * dens
        np.testing.assert_allclose(tr, np.exp(-sigma_t * length), rtol=1e-4)
