"""The twin process of a render loop (core/workers/forked.py, Workers.twin): both
processes compute half of every pass and exchange the rest, so the results
are those of one process; failures on either side end in an exception or in
the parent computing alone, never in a lost range or a leftover process."""

import os
import time

import numpy as np
import pytest

from restir_gi.core import RenderContext, RenderSettings, render_frame
from restir_gi.core.workers import forked
from restir_gi.core.workers.parallel import MIN_PIXELS_PER_WORKER, Workers
from restir_gi.core.render import render_restir
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from support.scenes import cornell_box
from support.twin_util import gone

pytestmark = pytest.mark.skipif(not forked.AVAILABLE, reason="fork and memfd_create: Linux only")

N = 4 * MIN_PIXELS_PER_WORKER       # two ranges


@pytest.fixture
def workers():
    """Two workers (a twin process in their loops), closed after the test."""
    w = Workers(2)
    yield w
    w.close()


def test01_passes_are_whole_in_the_parent_and_rows_written_in_place_arrive(workers):
    seen = np.zeros(N, np.int64)
    with workers.twin(N) as lead:
        assert forked.active() is not None
        pids = np.concatenate(workers.map(lambda a, b: np.full(b - a, os.getpid()), N))

        def fill(a, b):
            seen[a:b] = np.arange(a, b) * 3
            return np.arange(a, b)

        got = workers.map_into(fill, N, written=(seen,))
    assert lead and forked.active() is None
    assert np.array_equal(got, np.arange(N)) and np.array_equal(seen, np.arange(N) * 3)
    child = int(pids[-1])
    assert pids[0] == os.getpid() and child != os.getpid()     # the second half came from the child
    assert gone(child)


def test02_an_exception_in_the_childs_ranges_is_raised_in_the_parent(workers):
    def fn(a, b):
        if a > 0:
            raise ValueError(f"range {a} failed")
        return b - a

    with pytest.raises(ValueError, match="failed"):
        with workers.twin(N):
            workers.map(fn, N)
    assert forked.active() is None


def test03_a_child_that_dies_leaves_the_parent_to_finish_alone(workers):
    def fn(a, b):
        if a > 0 and forked.active() is not None and not forked.active().leader:
            os._exit(3)      # dies without a word
        return np.arange(a, b)

    with workers.twin(N):
        first = np.concatenate(workers.map(fn, N))
        second = np.concatenate(workers.map(fn, N))     # alone from here on
    assert np.array_equal(first, np.arange(N)) and np.array_equal(second, np.arange(N))


def test03b_a_child_that_hangs_is_left_and_the_parent_finishes_alone(workers, monkeypatch):
    """A child stuck in a pass (a lock another thread held at the fork) never
    answers: the parent waits WAIT_SECONDS, then computes its ranges too,
    and the child is killed."""
    monkeypatch.setattr(forked, "WAIT_SECONDS", 1.0)
    pids = []

    def fn(a, b):
        twin = forked.active()
        if a > 0 and twin is not None and not twin.leader:
            time.sleep(3600)
        if twin is not None and twin.leader:
            pids.append(twin.pid)
        return np.arange(a, b)

    t = time.perf_counter()
    with workers.twin(N):
        first = np.concatenate(workers.map(fn, N))
        second = np.concatenate(workers.map(fn, N))
    assert np.array_equal(first, np.arange(N)) and np.array_equal(second, np.arange(N))
    assert 1.0 <= time.perf_counter() - t < 30.0
    assert pids and pids[0] is not None and gone(pids[0])


def test04_an_exception_in_the_parent_ends_the_child(workers):
    pids = []

    def fn(a, b):
        pids.append(os.getpid())
        return np.full(b - a, os.getpid())

    with pytest.raises(KeyError):
        with workers.twin(N):
            child = int(np.concatenate(workers.map(fn, N))[-1])
            raise KeyError("cancelled")
    assert gone(child) and forked.active() is None


def test05_nested_passes_run_whole_on_each_side(workers):
    def inner(a, b):
        return np.arange(a, b)

    def outer(a, b):
        return np.concatenate(workers.map(inner, 3 * MIN_PIXELS_PER_WORKER))[a % 7:a % 7 + 1]

    with workers.twin(N):
        got = workers.map(outer, N)
    assert [int(g[0]) for g in got] == [0, (N // 2) % 7]


def test06_no_twin_without_processes_or_for_large_images():
    for workers, n in ((Workers(2, processes=False), N), (Workers(1), N), (Workers(2, max_range=N // 4), N)):
        try:
            with workers.twin(n) as lead:
                assert lead and forked.active() is None
        finally:
            workers.close()


@pytest.mark.slow
@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test07_restir_frames_of_a_twin_loop_are_those_of_one_process(contexts, mode):
    """A still's warm-up and the frames that follow it (render_restir's loop)
    give exactly the one-worker images, in both modes."""
    settings = ReSTIRSettings(mode=mode, max_bounces=2, seed=9)
    results = []
    for ctx in contexts:
        restir = ReSTIRGI()
        render_restir(ctx, restir, settings, 0, 4, fresh=True)
        results.append(render_restir(ctx, restir, settings, 1, 3))
    a, b = results
    assert a.history_found > 0.5
    for field in ("color", "direct", "indirect", "M", "W", "alpha"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test08_path_tracing_progress_and_stop_are_the_leaders():
    """on_sample reports from the parent only, and a stop there ends the loop
    (polled between batches: 96x96 traces 7 samples to a batch)."""
    scene = cornell_box("area", 96, 96)
    ctx = RenderContext.build(scene, threads=2)
    try:
        reports = []
        film = render_frame(ctx, RenderSettings(samples=20, max_bounces=2, seed=1),
                            on_sample=lambda film, s: reports.append(os.getpid()),
                            should_stop=lambda: len(reports) >= 7)
        assert reports == [os.getpid()] * 7 and film.count == 7
        assert forked.active() is None
        alone = RenderContext.build(scene, threads=1)
        try:
            three = render_frame(alone, RenderSettings(samples=7, max_bounces=2, seed=1))
        finally:
            alone.close()
        assert np.array_equal(film.mean(), three.mean())
    finally:
        ctx.close()


def test09_other_threads_of_the_process_do_not_take_part():
    """A pass run by another thread during a twin loop (the viewport's, while
    a final render runs) stays in this process, on threads."""
    import threading
    workers, other = Workers(2), Workers(2)
    try:
        got = {}
        with workers.twin(N) as lead:
            def run():
                got["pids"] = np.concatenate(other.map(lambda a, b: np.full(b - a, os.getpid()), N))
                got["twin"] = forked.active()
            if lead:        # (the twin has no other threads; its copies of the pools are idle)
                t = threading.Thread(target=run)
                t.start()
                t.join()
            mine = np.concatenate(workers.map(lambda a, b: np.full(b - a, os.getpid()), N))
        assert lead and got["twin"] is None and (got["pids"] == os.getpid()).all()
        assert mine[-1] != os.getpid()
    finally:
        workers.close()
        other.close()


def test10_a_loop_inside_a_twin_loop_keeps_its_roles(workers):
    with workers.twin(N) as lead:
        with workers.twin(N) as inner:
            roles = (lead, inner)
            child = int(np.concatenate(workers.map(lambda a, b: np.full(b - a, os.getpid()), N))[-1])
    assert roles == (True, True) and child != os.getpid() and gone(child)


@pytest.mark.slow
def test11_the_split_follows_where_the_time_goes(workers):
    """Rows of the upper half cost more: after a few passes the parent (lower
    half) takes more than half of the rows, and every pass is still whole."""
    import time as _time

    def fn(a, b):
        heavy = max(0, b - max(a, N // 2))
        _time.sleep(2e-5 * (heavy * 4 + (b - a)))
        return np.full(b - a, os.getpid())

    with workers.twin(N):
        shares = []
        for _ in range(6):
            pids = np.concatenate(workers.map(fn, N))
            assert len(pids) == N
            shares.append(float((pids == os.getpid()).mean()))
    assert shares[0] == 0.5 and shares[-1] > 0.6, shares


def test12_a_loop_run_by_another_thread_than_the_main_one(workers):
    """Blender renders F12 in a job thread: the twin forks from it (signals
    can only be set from the main thread) and the loop is whole."""
    import threading
    got = {}

    def job():
        with workers.twin(N) as lead:
            pids = np.concatenate(workers.map(lambda a, b: np.full(b - a, os.getpid()), N))
            got["ok"] = lead
        got["pids"] = pids

    t = threading.Thread(target=job)
    t.start()
    t.join(60)
    assert got.get("ok") is True and got["pids"][0] == os.getpid() and got["pids"][-1] != os.getpid()
    assert gone(int(got["pids"][-1]))


def test13_forking_a_process_with_threads_warns_nothing(workers):
    """Blender's process has threads; Python 3.12+ warns at every fork of such
    a process (the child may find a lock held), which the twin provides for
    (the parent goes on alone). The fork adds no warning to the render."""
    import threading
    import warnings
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with workers.twin(N) as lead:
                pids = np.concatenate(workers.map(lambda a, b: np.full(b - a, os.getpid()), N))
    finally:
        stop.set()
        other.join()
    assert lead and pids[-1] != os.getpid()
    assert not [str(w.message) for w in caught if "fork" in str(w.message)]


def test14_after_a_lost_twin_the_workers_fork_no_more():
    """A child that does not answer within the workers' own wait (seconds,
    factor) is left, and the next loop runs on threads instead of forking
    again (a viewport must not stall at every frame)."""
    workers = Workers(2, twin_wait=(0.5, 2.0))
    started = []

    def fn(a, b):
        twin = forked.active()
        if twin is not None and twin.leader and twin.pid not in started:
            started.append(twin.pid)
        if a > 0 and twin is not None and not twin.leader:
            time.sleep(3600)
        return np.arange(a, b)

    try:
        t = time.perf_counter()
        with workers.twin(N):
            first = np.concatenate(workers.map(fn, N))
        assert 0.5 <= time.perf_counter() - t < 10.0
        assert workers.processes is False
        with workers.twin(N) as lead:
            assert lead and forked.active() is None
            second = np.concatenate(workers.map(fn, N))
    finally:
        workers.close()
    assert np.array_equal(first, np.arange(N)) and np.array_equal(second, np.arange(N))
    assert len(started) == 1 and gone(started[0])


def test15_images_above_twin_max_pixels_stay_on_threads():
    workers = Workers(2, twin_max_pixels=N - 1)
    try:
        with workers.twin(N) as lead:
            assert lead and forked.active() is None
        with workers.twin(N - 1) as lead:
            assert lead and forked.active() is not None
    finally:
        workers.close()
