"""core.geometry.dynamic_accel against a static core.geometry.accel.Accel rebuilt over the same
triangles: the same closest hits and occlusion on random rays after objects
move, change their triangle count, appear and vanish; and the builds each
kind of edit costs."""

import numpy as np
import pytest

from restir_gi.core.geometry.accel import Accel
from restir_gi.core.geometry.dynamic_accel import DynamicAccel, TraceInterrupted


def make_objects(rng, count=6, per=40, spread=1.0):
    """Per-object vertex arrays of random triangles, each object a small cluster."""
    objects = []
    for _ in range(count):
        centre = rng.uniform(-spread, spread, 3)
        tri = centre + rng.uniform(-0.4, 0.4, (per, 1, 3)) + rng.normal(scale=0.15, size=(per, 3, 3))
        objects.append(tri.reshape(-1, 3).astype(np.float32))
    return objects


def combine(objects, keys=None):
    """Combined (vertices, triangles, object_ids, keys) of per-object triangle soups."""
    keys = list(range(len(objects))) if keys is None else list(keys)
    verts = np.concatenate(objects) if objects else np.zeros((0, 3), np.float32)
    counts = [len(v) // 3 for v in objects]
    tris = np.arange(len(verts), dtype=np.int32).reshape(-1, 3)
    ids = np.repeat(np.arange(len(objects)), counts).astype(np.int32)
    return verts, tris, ids, keys


def rays(rng, n=4000, vertices=None):
    """Random rays, half of them aimed at triangle centroids when vertices are given."""
    o = rng.uniform(-2.5, 2.5, (n, 3)).astype(np.float32)
    target = rng.uniform(-1.2, 1.2, (n, 3))
    if vertices is not None and len(vertices):
        centroids = vertices.reshape(-1, 3, 3).mean(axis=1)
        aimed = np.arange(n) % 2 == 0
        target[aimed] = centroids[rng.integers(0, len(centroids), aimed.sum())]
    d = target - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, d.astype(np.float32)


def assert_same_hits(dyn, ref, o, d, tmax=None):
    a = ref.intersect_closest(o, d, tmax)
    b = dyn.intersect_closest(o, d, tmax)
    assert a.hit.mean() > 0.2                           # the rays do test something
    np.testing.assert_array_equal(b.prim, a.prim)
    np.testing.assert_array_equal(b.t, a.t)
    np.testing.assert_array_equal(b.u, a.u)
    np.testing.assert_array_equal(b.v, a.v)
    dist = np.full(len(o), 1.5, np.float32) if tmax is None else tmax
    np.testing.assert_array_equal(dyn.occluded(o, d, dist), ref.occluded(o, d, dist))


def test01_static_matches_accel(rng):
    v, t, ids, keys = combine(make_objects(rng))
    dyn = DynamicAccel(v, t, ids, keys)
    assert (dyn.static_builds, dyn.dynamic_builds) == (1, 0)
    assert_same_hits(dyn, Accel(v, t), *rays(rng, vertices=v))


def test02_moved_objects_match_rebuilt_scene(rng):
    objects = make_objects(rng)
    v, t, ids, keys = combine(objects)
    dyn = DynamicAccel(v, t, ids, keys)
    o, d = rays(rng, vertices=v)
    tmax = rng.uniform(0.2, 4.0, len(o)).astype(np.float32)
    for step, moving in enumerate(([2], [2], [2, 4], [4])):
        for k in moving:
            objects[k] = objects[k] + rng.normal(scale=0.3, size=3).astype(np.float32)
        v, t, ids, keys = combine(objects)
        dyn.update(v, t, ids, keys, changed=moving)
        ref = Accel(v, t)
        assert_same_hits(dyn, ref, o, d)
        assert_same_hits(dyn, ref, o, d, tmax)
    assert dyn.dynamic_keys == {2, 4}


def test03_builds_per_edit(rng):
    objects = make_objects(rng)
    v, t, ids, keys = combine(objects)
    dyn = DynamicAccel(v, t, ids, keys)
    # First move of an object: the rest is built once without it, plus the small scene.
    assert dyn.update(v, t, ids, keys, changed=[1]) == ("static", "dynamic")
    # Further moves of the same object: the small scene only.
    for _ in range(3):
        assert dyn.update(v, t, ids, keys, changed=[1]) == ("dynamic",)
    assert (dyn.static_builds, dyn.dynamic_builds) == (2, 4)
    assert dyn.dynamic_triangle_count == len(objects[1]) // 3
    # No change: nothing built.
    assert dyn.update(v, t, ids, keys, changed=[]) == ()
    # Settling merges everything back into one scene.
    assert dyn.settle() == ("static",)
    assert dyn.dynamic_keys == set() and dyn.dynamic_triangle_count == 0
    assert_same_hits(dyn, Accel(v, t), *rays(rng, vertices=v))


def test03b_animated_objects_start_dynamic(rng):
    """Objects named as animated start in the small scene: their moves never
    rebuild the static one. With the combined arrays updated in place (the
    same object_ids array, as the add-on keeps them), a move skips the
    per-triangle partition and must still match a rebuilt scene."""
    objects = make_objects(rng)
    v, t, ids, keys = combine(objects)
    dyn = DynamicAccel(v, t, ids, keys, dynamic={3})
    assert (dyn.static_builds, dyn.dynamic_builds) == (1, 1) and dyn.dynamic_keys == {3}
    o, d = rays(rng, vertices=v)
    for _ in range(3):
        v[np.repeat(ids == 3, 3)] += rng.normal(scale=0.3, size=3).astype(np.float32)  # in place
        assert dyn.update(v, t, ids, keys, changed={3}) == ("dynamic",)
        assert_same_hits(dyn, Accel(v, t), o, d)
    assert dyn.static_builds == 1
    # Another object moving leaves the fast path: the static scene is rebuilt once.
    v[np.repeat(ids == 1, 3)] += np.float32(0.2)
    assert dyn.update(v, t, ids, keys, changed={1}) == ("static", "dynamic")
    assert_same_hits(dyn, Accel(v, t), o, d)


def test04_layout_changes(rng):
    """Triangle counts change, objects appear and vanish: the numbering of
    the combined scene shifts and the hits follow it."""
    objects = make_objects(rng)
    keys = ["a", "b", "c", "d", "e", "f"]
    v, t, ids, _ = combine(objects, keys)
    dyn = DynamicAccel(v, t, ids, keys)
    o, d = rays(rng, vertices=v)

    # "b" gets more triangles: everything after it is renumbered, the static
    # scene is built once (b leaves it), later growth only rebuilds b.
    objects[1] = np.concatenate([objects[1], make_objects(rng, 1, 10)[0]])
    v, t, ids, _ = combine(objects, keys)
    assert dyn.update(v, t, ids, keys, changed=["b"]) == ("static", "dynamic")
    assert_same_hits(dyn, Accel(v, t), o, d)
    objects[1] = objects[1][:-9 * 3]
    v, t, ids, _ = combine(objects, keys)
    assert dyn.update(v, t, ids, keys, changed=["b"]) == ("dynamic",)
    assert_same_hits(dyn, Accel(v, t), o, d)

    # A new object joins the dynamic scene; the static one is kept.
    objects.append(make_objects(rng, 1)[0])
    keys = keys + ["g"]
    v, t, ids, _ = combine(objects, keys)
    assert dyn.update(v, t, ids, keys, changed=["g"]) == ("dynamic",)
    assert_same_hits(dyn, Accel(v, t), o, d)

    # A dynamic object vanishes: only the small scene is rebuilt.
    del objects[1], keys[1]
    v, t, ids, _ = combine(objects, keys)
    assert dyn.update(v, t, ids, keys, changed=[]) == ("dynamic",)
    assert_same_hits(dyn, Accel(v, t), o, d)

    # A static object vanishes: the static scene must lose it.
    del objects[0], keys[0]
    v, t, ids, _ = combine(objects, keys)
    assert dyn.update(v, t, ids, keys, changed=[]) == ("static",)
    assert_same_hits(dyn, Accel(v, t), o, d)

    # The same objects in another order: both scenes' numberings are stale.
    assert dyn.update(v, t, ids, keys, changed=["c"]) == ("static", "dynamic")
    assert dyn.dynamic_keys == {"c", "g"}
    objects, keys = objects[::-1], keys[::-1]
    v, t, ids, _ = combine(objects, keys)
    assert dyn.update(v, t, ids, keys, changed=[]) == ("static", "dynamic")
    assert_same_hits(dyn, Accel(v, t), o, d)


@pytest.mark.parametrize("moving", [[], [0, 1, 2], [0]])
def test05_degenerate_partitions(rng, moving):
    """Everything dynamic, nothing dynamic, and a single object."""
    objects = make_objects(rng, count=3 if moving != [0] else 1)
    v, t, ids, keys = combine(objects)
    dyn = DynamicAccel(v, t, ids, keys)
    dyn.update(v, t, ids, keys, changed=moving)
    assert_same_hits(dyn, Accel(v, t), *rays(rng, vertices=v))


def test06_empty_scene(rng):
    v, t, ids, keys = combine([])
    dyn = DynamicAccel(v, t, ids, keys)
    o, d = rays(rng, 10)
    assert (dyn.intersect_closest(o, d).prim == -1).all()
    assert not dyn.occluded(o, d, np.ones(10, np.float32)).any()


def test07_bad_rays_and_counters(rng):
    objects = make_objects(rng, count=2)
    v, t, ids, keys = combine(objects)
    dyn = DynamicAccel(v, t, ids, keys)
    dyn.update(v, t, ids, keys, changed=[1])
    o, d = rays(rng, 100)
    o[3] = np.nan
    d[5] = np.inf
    hits = dyn.intersect_closest(o, d)
    assert hits.prim[3] == -1 and hits.prim[5] == -1
    assert not dyn.occluded(o, d, np.full(100, 10.0, np.float32))[[3, 5]].any()
    assert dyn.rays_traced == 200 and dyn.trace_seconds > 0


def test08_interrupt(rng):
    v, t, ids, keys = combine(make_objects(rng, count=2))
    dyn = DynamicAccel(v, t, ids, keys)
    dyn.interrupt = lambda: True
    with pytest.raises(TraceInterrupted):
        dyn.intersect_closest(*rays(rng, 10))
    with pytest.raises(TraceInterrupted):     # passes without queries poll between steps
        dyn.poll()
    dyn.interrupt = None
    dyn.poll()
    plain = Accel(v, t)
    plain.poll()                              # the plain structure is never interrupted
    plain.close()
    dyn.close()
    assert (dyn.intersect_closest(*rays(rng, 10)).prim == -1).all()


@pytest.mark.parametrize("count", [3, 400, 30_000])
def test_compact_keeps_used_vertices_in_order(rng, count):
    """_compact (sorting a few objects' indices, or marking every vertex for
    many) gives the vertices the triangles use, in index order, and the
    triangles re-indexed into them."""
    from restir_gi.core.geometry.dynamic_accel import _compact
    v = rng.random((20_000, 3)).astype(np.float32)
    t = rng.integers(0, len(v), (count, 3)).astype(np.int32)
    used = np.zeros(len(v), bool)
    used[t.ravel()] = True
    cv, ct = _compact(v, t)
    np.testing.assert_array_equal(cv, v[used])
    np.testing.assert_array_equal(ct, (np.cumsum(used) - 1)[t])
    assert ct.dtype == np.int32 and np.array_equal(cv[ct], v[t])
