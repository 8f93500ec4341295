"""Rays through transparent surfaces and past hidden objects (core/integrators/transparency.py)."""

import numpy as np

from restir_gi.core import Camera, Materials, make_scene
from restir_gi.core.integrators.base import RenderContext
from restir_gi.core.materials.shader import Link, Node, ShaderGraph
from restir_gi.core.integrators.transparency import TransparentAccel, _hash_uniform
from support.scenes import Builder, quad


def two_panes(alpha=0.5, visibility=None):
    """Two parallel quads facing -y at y = 0 (material 1, the graph) and y = 1
    (material 0, opaque); object ids 0 and 1."""
    b = Builder()
    b.add(*quad((-1, 0, -1), (0, 0, 2), (2, 0, 0)), 1)
    b.add(*quad((-1, 1, -1), (0, 0, 2), (2, 0, 0)), 0)
    v, t, m = b.arrays()
    oid = np.array([0, 0, 1, 1], np.int32)
    scene = make_scene(v, t, m, Materials.from_list([{}, {}]), camera=Camera(), object_ids=oid)
    scene.shaders = [None, ShaderGraph(nodes=[Node("BSDF_PRINCIPLED", {"Alpha": alpha})], output=Link(0, "BSDF"))]
    scene.ray_visibility = visibility
    return scene


def rays(n, rng):
    o = np.column_stack([rng.uniform(-0.9, 0.9, n), np.full(n, -2.0), rng.uniform(-0.9, 0.9, n)])
    return o.astype(np.float32), np.tile(np.float32([0, 1, 0]), (n, 1))


def test01_hash_is_uniform_and_deterministic(rng):
    prim = rng.integers(0, 1000, 200_000).astype(np.int32)
    t = rng.uniform(0, 10, 200_000).astype(np.float32)
    u = _hash_uniform(prim, t, 1)
    assert np.array_equal(u, _hash_uniform(prim, t, 1)) and not np.array_equal(u, _hash_uniform(prim, t, 2))
    hist = np.histogram(u, bins=20, range=(0, 1))[0] / len(u)
    assert np.abs(hist - 0.05).max() < 0.003 and u.min() >= 0 and u.max() < 1


def test02_half_transparent_pane_lets_half_through(rng):
    ctx = RenderContext.build(two_panes(0.5))
    assert isinstance(ctx.accel, TransparentAccel)
    o, d = rays(20_000, rng)
    hits = ctx.accel.intersect_closest(o, d)
    back = np.isin(hits.prim, [2, 3])
    assert abs(back.mean() - 0.5) < 0.02
    np.testing.assert_allclose(hits.t[back], 3.0, atol=1e-3)       # distances from the first origin
    np.testing.assert_allclose(hits.t[~back], 2.0, atol=1e-3)
    blocked = ctx.accel.occluded(o, d, np.full(len(o), 2.5, np.float32))
    assert abs(blocked.mean() - 0.5) < 0.02                          # shadows half as dark


def test03_opaque_and_clear_panes(rng):
    o, d = rays(2000, rng)
    opaque = RenderContext.build(two_panes(1.0))
    assert not isinstance(opaque.accel, TransparentAccel)            # nothing to pass: no wrapper
    assert (opaque.accel.intersect_closest(o, d).prim < 2).all()
    clear = RenderContext.build(two_panes(0.0))
    assert (np.isin(clear.accel.intersect_closest(o, d).prim, [2, 3])).all()
    assert not clear.accel.occluded(o, d, np.full(len(o), 2.5, np.float32)).any()


def test04_objects_hidden_from_some_rays(rng):
    """The front pane hidden from the camera: camera rays see the back pane,
    other rays and shadow rays still meet the front one; hidden from shadows:
    it casts none."""
    o, d = rays(2000, rng)
    vis = np.array([[False, True, True], [True, True, True]])
    ctx = RenderContext.build(two_panes(1.0, vis))
    assert (np.isin(ctx.accel.intersect_closest(o, d, camera=True).prim, [2, 3])).all()
    assert (ctx.accel.intersect_closest(o, d).prim < 2).all()
    assert ctx.accel.occluded(o, d, np.full(len(o), 2.5, np.float32)).all()
    ctx2 = RenderContext.build(two_panes(1.0, np.array([[True, False, True], [True, True, True]])))
    assert not ctx2.accel.occluded(o, d, np.full(len(o), 2.5, np.float32)).any()
    assert (ctx2.accel.intersect_closest(o, d, camera=True).prim < 2).all()


def test05_hidden_by_kind_of_bounce(rng):
    """Visibility (camera, shadow, diffuse, glossy, transmission): the front
    pane hidden from glossy rays only. Rays of paths pass it by their kind;
    without kinds (ReSTIR's reconnections) they are diffuse."""
    from restir_gi.core.integrators.bounces import DIFFUSE, GLOSSY, TRANSMISSION
    o, d = rays(3000, rng)
    vis = np.array([[True, True, True, False, True], [True] * 5])
    ctx = RenderContext.build(two_panes(1.0, vis))
    assert ctx.accel.per_kind_visibility
    kinds = np.array([DIFFUSE, GLOSSY, TRANSMISSION], np.int8)[np.arange(len(o)) % 3]
    behind = np.isin(ctx.accel.intersect_closest(o, d, kinds=kinds).prim, [2, 3])
    np.testing.assert_array_equal(behind, kinds == GLOSSY)
    assert (ctx.accel.intersect_closest(o, d).prim < 2).all()
    # The old (O, 3) form: diffuse stands for glossy and transmission.
    old = RenderContext.build(two_panes(1.0, np.array([[True, True, False], [True, True, True]])))
    assert not getattr(old.accel, "per_kind_visibility", False)
    assert np.isin(old.accel.intersect_closest(o, d).prim, [2, 3]).all()
