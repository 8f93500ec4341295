"""A render loop's twin process kept for the next loop (Workers.twin's
Continuation, core/workers/forked.py): parked after a completed loop and
resumed with the new camera or a ScenePatch, and after a loop the leader
abandoned (the viewport's frame, for an edit) when both processes' states
agree. Whatever happens, the images are those of one process."""

import os
import time

import numpy as np
import pytest

from restir_gi.core import RenderSettings, render_frame
from restir_gi.core.render import render_restir
from restir_gi.core.restir import BIASED, UNBIASED, ReSTIRGI, ReSTIRSettings
from restir_gi.core.workers import forked
from restir_gi.core.workers.parallel import MIN_PIXELS_PER_WORKER, Continuation, Workers
from support.twin_util import gone, moving, parked_pid

pytestmark = pytest.mark.skipif(not forked.AVAILABLE, reason="fork and memfd_create: Linux only")

N = 4 * MIN_PIXELS_PER_WORKER       # two ranges
PASSES = 4


@pytest.mark.parametrize("mode", [BIASED, UNBIASED])
def test01_an_animation_keeps_its_twin_while_only_the_camera_moves(contexts, mode):
    """Frames of a moving camera (render_restir per frame, as the add-on's
    animation renders) resume the parked twin instead of forking, and give
    the one-worker images; a geometry edit (its change counter) forks anew."""
    import dataclasses
    one, two = contexts
    settings = ReSTIRSettings(mode=mode, max_bounces=2, seed=5)
    images, pids = {}, []
    for base in (one, two):
        restir = ReSTIRGI()
        out = []
        for f in range(6):
            versions = (0, 0) if f < 4 else (1, 1)
            ctx = dataclasses.replace(base, scene=moving(base.scene, f, versions))
            out.append(render_restir(ctx, restir, settings, f, 3 if f == 0 else 1, fresh=f == 0).color.copy())
            if base is two:
                pids.append(parked_pid(two))
        images[base is two] = out
    for a, b in zip(images[False], images[True]):
        assert np.array_equal(a, b)
    assert None not in pids and len(set(pids[:4])) == 1 and pids[4] != pids[3] and pids[5] == pids[4]
    assert gone(pids[0])
    two.workers.end_twin()
    assert gone(pids[-1]) and two.workers._parked is None


def test02_a_stopped_loop_or_another_kind_of_loop_does_not_resume_the_twin(contexts):
    import dataclasses
    _, two = contexts
    restir = ReSTIRGI()
    settings = ReSTIRSettings(mode=BIASED, max_bounces=2, seed=5)
    ctx = dataclasses.replace(two, scene=moving(two.scene, 0))
    render_restir(ctx, restir, settings, 0, 2, fresh=True)
    first = parked_pid(two)
    calls = []
    render_restir(ctx, restir, settings, 1, 3, should_stop=lambda: calls.append(1) or len(calls) > 1)
    assert two.workers._parked is None and gone(first)      # stopped early: ended
    film = render_frame(ctx, RenderSettings(samples=2, max_bounces=2, seed=1), frame=1)
    pt = parked_pid(two)
    film2 = render_frame(dataclasses.replace(two, scene=moving(two.scene, 1)), RenderSettings(samples=2, max_bounces=2, seed=1), frame=2)
    assert parked_pid(two) == pt and film.count == film2.count == 2
    render_restir(ctx, restir, settings, 2, 1)          # a ReSTIR loop after path tracing: a new twin
    assert parked_pid(two) not in (None, pt) and gone(pt)
    two.workers.end_twin()




# --- a loop the leader abandons ------------------------------------------
#
# A toy loop of PASSES passes over a state (Workers, dict). The leader
# abandons pass ``stop_at`` between two passes or inside its half of one;
# ``child_writes`` makes the twin's half of every pass write into the state,
# so the two states differ after an abandon.

def _pass(box, i, stop_inside, child_writes):
    parent = box["parent"]

    def fn(a, b):
        if os.getpid() == parent and stop_inside:
            raise forked.LoopAbandoned()
        if os.getpid() != parent and child_writes:
            box["written"] = box.get("written", 0) + 1
        return np.arange(a, b) * (i + 1)
    return fn


def _loop(w, box, stop_at=None, inside=False, child_writes=False):
    """Returns (whole passes, pid of each pass's last range)."""
    keep = Continuation(lambda: ("toy", box["loops"]), (w, box), _resume_loop, (stop_at, inside, child_writes),
                        fingerprint=_fingerprint)
    out = []
    with w.twin(N, keep) as lead:
        for i in range(PASSES):
            if lead and i == stop_at and not inside:
                raise forked.LoopAbandoned()
            fn = _pass(box, i, lead and i == stop_at and inside, child_writes)
            got = np.concatenate(w.map(fn, N))
            assert np.array_equal(got, np.arange(N) * (i + 1))
            pids = np.concatenate(w.map(lambda a, b: np.full(b - a, os.getpid()), N))
            out.append(int(pids[-1]))
        if lead and stop_at == PASSES:      # after the last pass: the twin completes the loop
            raise forked.LoopAbandoned()
        box["loops"] += 1
        keep.complete = True
    return out


def _resume_loop(w, box, patch, stop_at, inside, child_writes):
    try:
        _loop(w, box, stop_at, inside, child_writes)
    except forked.LoopAbandoned:
        pass
    return w, box


def _parked(w):
    return None if w._parked is None else w._parked[0].pid


def _fingerprint(w, box):
    return sorted(box.items())


@pytest.mark.parametrize("inside", [False, True], ids=["between-passes", "inside-a-pass"])
@pytest.mark.parametrize("first", [True, False], ids=["first-loop", "resumed-loop"])
def test03_an_abandoned_loop_keeps_its_twin_when_both_states_agree(inside, first):
    w = Workers(2)
    box = {"loops": 0, "parent": os.getpid()}
    try:
        before = None if first else _loop(w, box)
        with pytest.raises(forked.LoopAbandoned):
            _loop(w, box, stop_at=2, inside=inside)
        kept = _parked(w)
        assert kept is not None and kept != os.getpid()
        assert before is None or set(before) == {kept}
        after = _loop(w, box)           # resumes the kept twin: its halves, right
        assert set(after) == {kept} and _parked(w) == kept
    finally:
        w.close()
    assert gone(kept)


def test04_an_abandoned_loop_whose_states_differ_forks_anew():
    w = Workers(2)
    box = {"loops": 0, "parent": os.getpid()}
    try:
        first = _loop(w, box)
        with pytest.raises(forked.LoopAbandoned):
            _loop(w, box, stop_at=2, child_writes=True)     # the twin's state has "written"
        assert w._parked is None and gone(first[0])
        after = _loop(w, box)
        assert after[0] not in (first[0], os.getpid()) and len(set(after)) == 1
    finally:
        w.close()


def test05_a_twin_that_finished_the_loop_the_leader_abandoned_is_ended():
    """The leader stops after the last pass: the twin completed the loop
    (its state is a loop ahead) and exits when told."""
    w = Workers(2)
    box = {"loops": 0, "parent": os.getpid()}
    try:
        first = _loop(w, box)
        with pytest.raises(forked.LoopAbandoned):
            _loop(w, box, stop_at=PASSES)
        assert w._parked is None and gone(first[0])
        after = _loop(w, box)
        assert after[0] not in (first[0], os.getpid())
    finally:
        w.close()


def _slow_loop(w, box, where):
    """The twin's side is slow (2 s) where the leader abandons: in its half
    of a pass, or in serial work between two passes. Both poll the stop word
    (forked.told_to_stop) as the interruptible ray queries do."""
    def linger():
        for _ in range(200):
            if forked.told_to_stop():
                raise forked.LoopAbandoned()
            time.sleep(0.01)

    def fn(a, b):
        if forked.in_twin() and where == "pass":
            linger()
        if not forked.in_twin() and where == "pass":
            raise forked.LoopAbandoned()
        return np.arange(a, b)

    keep = Continuation(lambda: ("toy", box["loops"]), (w, box), _resume_slow, (where,),
                        fingerprint=_fingerprint)
    with w.twin(N, keep) as lead:
        for i in range(PASSES):
            np.concatenate(w.map(fn if i == 1 else (lambda a, b: np.arange(a, b)), N))
            if i == 1 and where == "serial":
                if lead:
                    raise forked.LoopAbandoned()
                linger()
        box["loops"] += 1
        keep.complete = True


def _resume_slow(w, box, patch, where):
    try:
        _slow_loop(w, box, where)
    except forked.LoopAbandoned:
        pass
    return w, box


@pytest.mark.parametrize("where", ["pass", "serial"])
def test06_the_twin_stops_at_its_next_poll_not_at_the_end_of_its_work(where):
    w = Workers(2)
    box = {"loops": 0, "parent": os.getpid()}
    try:
        _loop(w, box)
        kept = _parked(w)
        t = time.perf_counter()
        with pytest.raises(forked.LoopAbandoned):
            _slow_loop(w, box, where)
        assert time.perf_counter() - t < 1.0        # not the twin's 2 s
        assert _parked(w) == kept
        assert set(_loop(w, box)) == {kept}         # and it goes on in step
    finally:
        w.close()
