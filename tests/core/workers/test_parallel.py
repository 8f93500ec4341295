"""Whole-image passes on worker threads (core/workers/parallel.py): the split into
pixel ranges changes nothing in the result, for path tracing and for every
ReSTIR GI pass (each range uses the image-wide pixel index for its random
numbers and reads neighbours from the whole image)."""

import dataclasses

import numpy as np
import pytest

from restir_gi.core import RenderContext, RenderSettings, render_frame
from restir_gi.core.workers.parallel import MIN_PIXELS_PER_WORKER, Workers, concat_rows
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from support.scenes import cornell_box

W, H = 96, 96           # large enough for two ranges of MIN_PIXELS_PER_WORKER


def test01_ranges_cover_the_image_once():
    workers = Workers(2)
    try:
        for n in (0, 1, MIN_PIXELS_PER_WORKER, 2 * MIN_PIXELS_PER_WORKER + 3, 100_000):
            ranges = workers.ranges(n)
            assert ranges[0][0] == 0 and ranges[-1][1] == n
            assert all(a1 == b0 for (_, b0), (a1, _) in zip(ranges, ranges[1:]))
            assert len(ranges) == (2 if n >= 2 * MIN_PIXELS_PER_WORKER else 1)
        got = concat_rows(workers.map(lambda a, b: np.arange(a, b), 100_000))
        assert np.array_equal(got, np.arange(100_000))
    finally:
        workers.close()


@pytest.fixture(scope="module")
def contexts():
    scene = cornell_box("area", W, H)
    serial, parallel = RenderContext.build(scene, threads=1), RenderContext.build(scene, threads=2)
    assert len(parallel.workers.ranges(W * H)) == 2
    yield serial, parallel
    serial.close()
    parallel.close()


def test02_path_tracing_is_the_same_on_two_workers(contexts):
    films = [render_frame(ctx, RenderSettings(samples=2, max_bounces=3, seed=4)) for ctx in contexts]
    assert np.array_equal(films[0].mean(), films[1].mean())


@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test03_restir_is_the_same_on_two_workers(contexts, mode):
    settings = ReSTIRSettings(mode=mode, max_bounces=2, seed=9)
    results = []
    for ctx in contexts:
        restir = ReSTIRGI()
        frames = [restir.render_frame(ctx, settings, f) for f in range(4)]
        results.append(frames[-1])
    a, b = results
    assert a.history_found > 0.5
    for field in ("color", "direct", "indirect", "M", "W"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test03b_many_small_ranges_give_the_same_image(contexts, mode):
    """Passes split into many more ranges than workers (bounded temporaries
    for large images) give the image of one range."""
    serial, parallel = contexts
    small = dataclasses.replace(parallel, workers=Workers(2, max_range=1500))
    try:
        assert len(small.workers.ranges(W * H)) == 7
        settings = ReSTIRSettings(mode=mode, max_bounces=2, seed=9)
        results = []
        for ctx in (serial, small):
            restir = ReSTIRGI()
            results.append([restir.render_frame(ctx, settings, f) for f in range(3)][-1])
        for field in ("color", "direct", "indirect", "M", "W"):
            assert np.array_equal(getattr(results[0], field), getattr(results[1], field)), field
        films = [render_frame(ctx, RenderSettings(samples=1, max_bounces=2, seed=3)) for ctx in (serial, small)]
        assert np.array_equal(films[0].mean(), films[1].mean())
    finally:
        small.workers.close()


def test03c_consuming_concatenation_matches_and_empties_the_parts():
    """concat_rows(consume=True) gives what np.concatenate gives, for arrays,
    tuples and dataclasses, and leaves nothing of the parts behind."""
    from restir_gi.core.restir.reservoirs import Reservoirs
    rng = np.random.default_rng(3)

    def parts():
        out = []
        for n in (5, 0, 7):
            res = Reservoirs.empty(n)
            res.w_sum[:] = rng.random(n)
            out.append((np.arange(n) * 2, res))
        return out

    a, b = parts(), parts()
    for x, y in zip(a, b):
        y[1].w_sum[:] = x[1].w_sum
    plain = concat_rows(a)
    consumed_from = b
    eaten = concat_rows(consumed_from, consume=True)
    assert consumed_from == []
    assert np.array_equal(plain[0], eaten[0])
    for f in plain[1].__dataclass_fields__:
        assert np.array_equal(getattr(plain[1], f), getattr(eaten[1], f)), f


def test03d_map_into_writes_each_range_into_whole_image_arrays():
    """Workers.map_into gives what concat_rows of map gives, for arrays,
    tuples and dataclasses, into arrays it allocates or the caller's (which
    may be of narrower types)."""
    from restir_gi.core.restir.reservoirs import Reservoirs
    n = 3 * MIN_PIXELS_PER_WORKER + 11
    workers = Workers(2, max_range=1000)
    try:
        def fn(a, b):
            res = Reservoirs.empty(b - a)
            res.w_sum[:] = np.arange(a, b) * 0.5
            return np.arange(a, b) * 2, res, None

        plain = concat_rows(workers.map(fn, n))
        into = workers.map_into(fn, n)
        assert into[2] is None and np.array_equal(plain[0], into[0])
        stored = into[1].take(np.arange(n))     # Reservoirs go into their narrow store
        for f in plain[1].__dataclass_fields__:
            assert np.array_equal(getattr(plain[1], f), getattr(stored, f)), f
        mine = np.zeros(n, np.int32)
        out = workers.map_into(lambda a, b: np.arange(a, b), n, out=mine)
        assert out is mine and np.array_equal(mine, np.arange(n))
    finally:
        workers.close()


def test04_a_failing_range_waits_for_the_others():
    """An exception in one range (a cancelled trace) is raised only after every
    other range has finished, so nothing runs on after the call."""
    import threading
    import time as _time
    finished = []
    workers = Workers(2)
    try:
        def fn(a, b):
            if a == 0:
                raise RuntimeError("cancelled")
            _time.sleep(0.2)
            finished.append(threading.current_thread().name)
            return b - a

        with pytest.raises(RuntimeError, match="cancelled"):
            workers.map(fn, 4 * MIN_PIXELS_PER_WORKER)
        assert len(finished) == 1
    finally:
        workers.close()


def moving_pair(x, size=96):
    """A floor under a point light, a card moving diagonally in the lower
    half of the image and a thin pole moving the other way in the upper."""
    from restir_gi.core import Camera, Lights, Materials, make_scene
    from restir_gi.core.scene import LIGHT_POINT
    from support.scenes import Builder, look_at, quad
    b = Builder()
    b.add(*quad((-4, -4, 0), (8, 0, 0), (0, 8, 0)), 0)
    b.add(*quad((-0.6 + x, 2.0 + 0.7 * x, 0.0), (1.2, 0, 0), (0, 0, 1.0)), 1)
    b.add(*quad((-0.03 - x, -1.5 + 0.7 * x, 0.0), (0.06, 0, 0), (0, 0, 0.5)), 2)
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": (0, 0, 3.0), "power": (400.0,) * 3}])
    cam = Camera(to_world=look_at((0, -4, 3), (0, 0, 0.3)), lens=35.0, sensor_width=36.0)
    mats = Materials.from_list([{"base_color": (0.8, 0.8, 0.8)}, {"base_color": (0.8, 0.6, 0.3)}])
    scene = make_scene(*b.arrays(), mats, lights, cam, object_ids=np.array([0, 0, 1, 1, 2, 2]),
                       width=size, height=size)
    m1, m2 = np.eye(4), np.eye(4)
    m1[0, 3], m1[1, 3] = x, 0.7 * x
    m2[0, 3], m2[1, 3] = -x, 0.7 * x
    scene.object_keys = ["floor", "card", "pole"]
    scene.object_matrices = np.stack([np.eye(4), m1, m2])
    return scene


@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test05_moving_objects_give_the_same_image_on_two_workers(mode):
    """Objects moving diagonally (history read through the running means'
    outer Catmull-Rom taps in some rows of a range only): the same frames on
    one and two workers. The clip of that history to its inner taps was
    decided per range, so pixels starting over took history or not with the
    other rows of their range."""
    from restir_gi.core.integrators import transparency
    from restir_gi.core.geometry.dynamic_accel import DynamicAccel
    from restir_gi.core.integrators.base import RAY_EPS_RELATIVE
    from restir_gi.core.lights.light_set import LightSet
    settings = ReSTIRSettings(mode=mode, seed=5, max_bounces=3)
    frames = {}
    for threads in (1, 2):
        restir, out, accel = ReSTIRGI(), [], None
        workers = Workers(threads, processes=False)
        try:
            for f, x in enumerate((0.0, 0.05, 0.1, 0.15, 0.2)):
                scene = moving_pair(x)      # (the objects in Embree's dynamic scene, as the add-on's)
                if accel is None:
                    accel = DynamicAccel(scene.vertices, scene.triangles, scene.object_ids,
                                         scene.object_keys, threads, dynamic={"card", "pole"})
                else:
                    accel.update(scene.vertices, scene.triangles, scene.object_ids, scene.object_keys,
                                 changed={"card", "pole"})
                ctx = RenderContext(scene, transparency.wrap(accel, scene), LightSet(scene),
                                    RAY_EPS_RELATIVE * scene.extent(), workers)
                out.append(restir.render_frame(ctx, settings, f))
        finally:
            workers.close()
            accel.close()
        frames[threads] = out
    for f, (a, b) in enumerate(zip(frames[1], frames[2])):
        for field in ("color", "direct", "indirect"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), (f, field)
