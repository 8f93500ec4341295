"""Emitters chosen by where the shading point is (core/lights/light_grid.py): the
probabilities are a distribution at every point, sampling follows them, the
near emitters get more and none falls below its defensive share of power, and
next-event estimation over many lamps stays unbiased."""

import numpy as np
import pytest

from support.chi2 import pooled_chi2
from restir_gi.core.lights.light_grid import DEFENSIVE, MAX_CLUSTERS, LightGrid
from restir_gi.core.lights.light_set import LightSet
from restir_gi.core import Materials
from restir_gi.core.scene import LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, Lights, make_scene


def random_grid(rng, count, lo=(-4, -3, 0), hi=(4, 3, 3)):
    lo, hi = np.float64(lo), np.float64(hi)
    centre = rng.uniform(lo, hi, (count, 3))
    half = rng.uniform(0.01, 0.2, (count, 1))
    power = rng.uniform(0.1, 10.0, count)
    power[::7] = 0.0                                    # some emit nothing
    return LightGrid(lo, hi, power, centre - half, centre + half), power, centre


@pytest.mark.parametrize("count", [2, 40, 300])
def test_sampling_follows_the_pmf_everywhere(count, rng):
    grid, power, _ = random_grid(rng, count)
    assert grid.k == min(count, MAX_CLUSTERS)
    assert np.allclose(grid.cell_pmf.sum(axis=1), 1.0)
    for p in ([-3.9, -2.9, 0.1], [0.0, 0.0, 1.5], [3.5, 2.0, 2.9], [9.0, -9.0, -1.0]):   # the last outside
        pmf = grid.pmf(np.arange(count), np.repeat([p], count, axis=0))
        assert np.isclose(pmf.sum(), 1.0) and (pmf[power == 0] == 0).all()
        n = 200_000
        light, q = grid.sample(np.repeat([p], n, axis=0), rng.random(n))
        assert np.allclose(q, pmf[light]) and (power[light] > 0).all()
        p_value, *_ = pooled_chi2(np.bincount(light, minlength=count), pmf * n)
        assert p_value > 0.001, (count, p)


def test_near_emitters_get_more_and_none_less_than_its_share():
    power = np.ones(30)
    centre = np.stack([np.linspace(-3.8, 3.8, 30), np.zeros(30), np.full(30, 1.5)], 1)
    grid = LightGrid((-4, -3, 0), (4, 3, 3), power, centre - 0.05, centre + 0.05)
    p = np.repeat([[-3.8, 0.0, 1.4]], 30, axis=0)           # beside the first lamp
    pmf = grid.pmf(np.arange(30), p)
    assert pmf[0] > 8 * pmf[-1] and pmf[0] > 3.0 / 30
    assert (pmf >= DEFENSIVE / 30 * (1 - 1e-9)).all()


def test_a_point_beside_an_emitter_chooses_it_more_than_its_cell_does():
    """Two points of one cell, 2 cm and 25 cm from the same small lamp: the
    near one gives it over twice the probability (each point weighs its
    cell's top clusters by its own distance), and both stay distributions."""
    power = np.ones(30)
    centre = np.stack([np.linspace(-3.8, 3.8, 30), np.zeros(30), np.full(30, 1.5)], 1)
    grid = LightGrid((-4, -3, 0), (4, 3, 3), power, centre - 0.02, centre + 0.02)
    lamp = 15
    near = centre[lamp] + [0.0, 0.0, -0.04]
    far = centre[lamp] + [0.0, 0.0, -0.25]
    assert grid.cells(np.float32([near]))[0] == grid.cells(np.float32([far]))[0]
    at = [grid.pmf(np.arange(30), np.repeat([q], 30, axis=0).astype(np.float32)) for q in (near, far)]
    assert np.allclose([a.sum() for a in at], 1.0)
    assert at[0][lamp] > 2 * at[1][lamp] and at[0][lamp] > 0.45      # the same under the cell alone


def test_a_point_gives_little_to_lamps_at_grazing_angles_to_its_surface(rng):
    """With its normal, a floor point weighs a lamp level with it far below
    one overhead at the same distance, and sampling with normals follows the
    probabilities given the same normals."""
    power = np.ones(3)
    centre = np.float64([[0.3, 0.0, 0.05], [0.0, 0.3, 0.05], [0.0, 0.0, 0.3]])
    grid = LightGrid((-4, -3, 0), (4, 3, 3), power, centre - 0.01, centre + 0.01)
    p = np.zeros((3, 3), np.float32)
    up = np.repeat([[0.0, 0.0, 1.0]], 3, axis=0).astype(np.float32)
    with_n = grid.pmf(np.arange(3), p, n=up)
    without = grid.pmf(np.arange(3), p)
    assert np.isclose(with_n.sum(), 1.0) and np.isclose(without.sum(), 1.0)
    assert with_n[2] > 2 * with_n[0] and without[2] < 1.2 * without[0]     # half goes by the cell
    count = 100_000
    light, q = grid.sample(np.zeros((count, 3), np.float32), rng.random(count),
                           np.repeat(up[:1], count, axis=0))
    assert np.allclose(q, with_n[light])
    p_value, *_ = pooled_chi2(np.bincount(light, minlength=3), with_n * count)
    assert p_value > 0.001


def test_degenerate_layouts_stay_distributions(rng):
    for lo, hi, centre in [((0, 0, 0), (0, 0, 0), np.zeros((5, 3))),             # a point scene
                           ((-1, -1, 0), (1, 1, 0), rng.uniform(-1, 1, (9, 3))),  # flat
                           ((0, 0, 0), (1, 1, 1), np.full((4, 3), 50.0)),         # lamps far outside
                           ((0, 0, 0), (np.inf, 1, 1), np.float64([[0, 0, 0], [np.nan, 0, 0]]))]:
        grid = LightGrid(lo, hi, np.ones(len(centre)), centre, centre)
        p = rng.uniform(-2, 2, (len(centre), 3))
        for row in p:
            pmf = grid.pmf(np.arange(len(centre)), np.repeat([row], len(centre), axis=0))
            assert np.isfinite(pmf).all() and np.isclose(pmf.sum(), 1.0)


def lamps_and_panels(rng, count=14):
    """Small sphere lamps and emissive triangles spread over a 10 m floor."""
    rows = [{"kind": LIGHT_POINT, "position": (x, y, z), "power": tuple(rng.uniform(20, 200, 3)),
             "radius": 0.05} for x, y, z in rng.uniform((-5, -5, 0.3), (5, 5, 2.0), (count, 3))]
    tris = []
    for x, y in rng.uniform(-5, 5, (4, 2)):
        tris += [[x, y, 2.5], [x + 0.3, y, 2.5], [x, y + 0.3, 2.4]]
    floor = [[-5, -5, 0], [5, -5, 0], [5, 5, 0]]
    v = np.float32(tris + floor)
    t = np.arange(len(v), dtype=np.int32).reshape(-1, 3)
    mats = Materials.from_list([{"emission": (6, 5, 4)}, {"base_color": (0.5, 0.5, 0.5)}])
    mids = np.r_[np.zeros(len(tris) // 3), 1].astype(np.int32)
    return rows, v, t, mats, mids


def irradiance(ls, p, n, rng, count):
    P = np.repeat([p], count, axis=0).astype(np.float32)
    s = ls.sample(P, rng.random(count, dtype=np.float32), rng.random((count, 2), dtype=np.float32))
    cos = np.maximum(s.wi.astype(np.float64) @ n, 0.0)
    val = np.where((s.pdf > 0)[:, None], s.radiance * (cos / np.where(s.pdf > 0, s.pdf, 1))[:, None], 0.0)
    return val.mean(axis=0), val.std(axis=0) / np.sqrt(count)


def test_nee_over_many_emitters_is_unbiased(rng):
    """NEE with the grid gives the sum of each emitter's own NEE estimate
    (one emitter: no choice to make), at points near and far from them."""
    rows, v, t, mats, mids = lamps_and_panels(rng)
    scene = make_scene(v, t, material_ids=mids, materials=mats, lights=Lights.from_list(rows))
    ls = LightSet(scene)
    assert ls.grid is not None and ls.grid.count == len(rows) + 4
    n = np.float64([0, 0, 1])
    for p in ([-4.5, -4.5, 0.0], [0.0, 0.0, 0.0], [3.0, 4.0, 0.0]):
        est, err = irradiance(ls, p, n, rng, 300_000)
        ref, ref_err = np.zeros(3), np.zeros(3)
        for row in rows:
            one = LightSet(make_scene(v[-3:], t[:1], materials=mats, material_ids=np.int32([1]),
                                      lights=Lights.from_list([row])))
            e, r = irradiance(one, p, n, rng, 20_000)
            ref, ref_err = ref + e, np.hypot(ref_err, r)
        for k in range(4):
            panel = make_scene(np.r_[v[3 * k:3 * k + 3], v[-3:]], np.int32([[0, 1, 2], [3, 4, 5]]),
                               materials=mats, material_ids=np.int32([0, 1]), lights=Lights.empty())
            e, r = irradiance(LightSet(panel), p, n, rng, 20_000)
            ref, ref_err = ref + e, np.hypot(ref_err, r)
        assert (np.abs(est - ref) <= 4.5 * np.hypot(err, ref_err) + 1e-9).all(), (p, est, ref)
        assert (err < 0.02 * est).all()


def test_one_lamp_of_two_triangles_is_chosen_by_power_alone():
    """Where the grid would choose as power does (a ceiling panel's two
    triangles), the light set does without it."""
    v = np.float32([[-0.3, -0.3, 2.9], [0.3, -0.3, 2.9], [0.3, 0.3, 2.9], [-0.3, 0.3, 2.9],
                    [-3, -3, 0], [3, -3, 0], [3, 3, 0]])
    t = np.int32([[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    mats = Materials.from_list([{"emission": (5, 5, 5)}, {"base_color": (0.5, 0.5, 0.5)}])
    ls = LightSet(make_scene(v, t, material_ids=np.int32([0, 0, 1]), materials=mats, lights=Lights.empty()))
    assert ls.count == 2 and ls.grid is None


def spots_and_panels(rng):
    """Downlights (30 degree half cones) and ceiling panels facing down, over a 10 m floor."""
    rows = []
    for x, y in rng.uniform(-4.5, 4.5, (8, 2)):
        rows.append({"kind": LIGHT_SPOT, "position": (x, y, 2.0), "direction": (0, 0, -1),
                     "power": (300, 280, 250), "radius": 0.05, "spot_size": np.radians(60),
                     "spot_blend": 0.2})
    for x, y in rng.uniform(-4.5, 4.5, (4, 2)):
        rows.append({"kind": LIGHT_AREA, "position": (x, y, 2.9), "direction": (0, 0, -1),
                     "axis_u": (1, 0, 0), "axis_v": (0, -1, 0), "power": (100, 100, 100),
                     "size_u": 0.5, "size_v": 0.5})
    floor = np.float32([[-5, -5, 0], [5, -5, 0], [5, 5, 3], [-5, 5, 3]])
    return rows, floor


def test_emitters_facing_away_are_chosen_by_power_alone(rng):
    rows, floor = spots_and_panels(rng)
    scene = make_scene(floor, np.int32([[0, 1, 2], [0, 2, 3]]), lights=Lights.from_list(rows))
    ls = LightSet(scene)
    assert ls.grid is not None
    idx = np.arange(len(rows))
    power = np.array([ls._weights[i] for i in idx])
    share = DEFENSIVE * power / power.sum()
    above = ls.selection_pmf(idx, np.repeat([[rows[0]["position"][0], rows[0]["position"][1], 2.98]],
                                            len(rows), axis=0))
    assert np.allclose(above[:8], share[:8], rtol=1e-6)         # no spot shines up
    below = ls.selection_pmf(idx, np.repeat([[rows[0]["position"][0], rows[0]["position"][1], 0.05]],
                                            len(rows), axis=0))
    assert below[0] > 3 * share[0] / DEFENSIVE     # over 3x what its power alone gives it


@pytest.mark.slow
def test_nee_with_spots_and_panels_is_unbiased(rng):
    rows, floor = spots_and_panels(rng)
    tri = np.int32([[0, 1, 2], [0, 2, 3]])
    ls = LightSet(make_scene(floor, tri, lights=Lights.from_list(rows)))
    assert ls.grid is not None
    n = np.float64([0, 0, 1])
    for p in ([-4.0, -4.0, 0.0], [0.5, 0.5, 1.0], [3.5, 2.0, 2.0]):
        est, err = irradiance(ls, p, n, rng, 300_000)
        ref, ref_err = np.zeros(3), np.zeros(3)
        for row in rows:
            e, r = irradiance(LightSet(make_scene(floor, tri, lights=Lights.from_list([row]))), p, n, rng, 20_000)
            ref, ref_err = ref + e, np.hypot(ref_err, r)
        assert (np.abs(est - ref) <= 4.5 * np.hypot(err, ref_err) + 1e-9).all(), (p, est, ref)
