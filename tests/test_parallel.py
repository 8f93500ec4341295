"""Whole-image passes on worker threads (core/parallel.py): the split into
pixel ranges changes nothing in the result, for path tracing and for every
ReSTIR GI pass (each range uses the image-wide pixel index for its random
numbers and reads neighbours from the whole image)."""

import dataclasses

import numpy as np
import pytest

from core import RenderContext, RenderSettings, render_frame
from core.parallel import MIN_PIXELS_PER_WORKER, Workers, concat_rows
from core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from scenes import cornell_box

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
    from core.reservoirs import Reservoirs
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
    from core.reservoirs import Reservoirs
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
