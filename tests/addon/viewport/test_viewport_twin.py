"""The viewport's frames (ReSTIR, and path-traced samples) in two processes (core/workers/forked.py):
the twin is forked once and kept between frames while the view turns and an
object moves, and across a frame abandoned for an edit; the images are
bitwise those of two threads, and those of a twin forked anew after the
abandoned frame."""

import dataclasses
import math

import numpy as np
import pytest

from support.viewport_util import build_scene, new_session

SIZE = (128, 96)        # two pixel ranges: the twin's size (parallel.MIN_PIXELS_PER_WORKER)


def _turned(camera, degrees):
    a = math.radians(degrees)
    rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    m = camera.to_world.copy()
    m[:3, :3] = rot @ m[:3, :3]
    return dataclasses.replace(camera, to_world=m)


def _abandon(vp, session, nth):
    """Render a frame the leader abandons at its nth poll of the interrupt
    (an edit arriving then)."""
    accel = session._accel
    polls, interrupt = [0], accel.interrupt

    def edit_arrives():
        polls[0] += 1
        return polls[0] == nth or interrupt()
    accel.interrupt = edit_arrives
    try:
        with pytest.raises(vp.TraceInterrupted):
            session.render_step()
    finally:
        accel.interrupt = interrupt
    return polls[0]


def _frames(vp, recorder, twin, monkeypatch, abandon_at=None, mode="RESTIR_BIASED"):
    import bpy
    monkeypatch.setattr(vp.ViewportSession, "twin_process", twin)
    build_scene()
    session = new_session(vp, mode=mode, samples=0, threads=2)
    session.resize(*SIZE)
    frames = []

    def render(n):
        for _ in range(n):
            assert session.render_step()
            frames.append(session.frame.copy())

    render(3)
    if abandon_at is not None:
        assert _abandon(vp, session, abandon_at) == abandon_at
    session.set_view(_turned(session.view, 2.0))
    render(2)
    mover = bpy.data.objects["Mover"]
    session.sync(bpy.context.evaluated_depsgraph_get(),
                 recorder.edit(lambda: setattr(mover, "location", (0.6, -0.4, 0.3))))
    render(2)
    assert session.render_size == SIZE
    session.close()
    return frames


@pytest.mark.parametrize("mode", ["RESTIR_BIASED", "PATH"])
def test01_frames_of_the_twin_are_those_of_threads_and_it_is_kept(vp, recorder, monkeypatch, mode):
    from restir_gi.core.workers import forked
    if not forked.AVAILABLE:
        pytest.skip("no fork on this platform")
    calls = {"start": 0, "resume": 0}
    start, resume = forked.Twin.start, forked.Twin.resume

    def counted_start(*args, **kw):
        calls["start"] += 1
        return start(*args, **kw)

    def counted_resume(self, fn, args):
        resumed = resume(self, fn, args)
        calls["resume"] += resumed
        return resumed

    monkeypatch.setattr(forked.Twin, "start", staticmethod(counted_start))
    monkeypatch.setattr(forked.Twin, "resume", counted_resume)
    threads = _frames(vp, recorder, False, monkeypatch, mode=mode)
    assert calls == {"start": 0, "resume": 0}
    twin = _frames(vp, recorder, True, monkeypatch, mode=mode)
    # One fork for the first frame; the six after it resume the parked twin
    # (the object's move is sent as a ScenePatch) or fork again at most once.
    assert calls["start"] <= 2 and calls["resume"] >= 5, calls
    assert len(twin) == len(threads) == 7
    for i, (a, b) in enumerate(zip(twin, threads)):
        assert np.isfinite(a).all()
        assert np.array_equal(a, b), f"frame {i}"


def _count_forks(monkeypatch, forked):
    calls = {"start": 0}
    start = forked.Twin.start

    def counted_start(*args, **kw):
        calls["start"] += 1
        return start(*args, **kw)
    monkeypatch.setattr(forked.Twin, "start", staticmethod(counted_start))
    return calls


@pytest.mark.parametrize("mode, nth", [("RESTIR_BIASED", 1), ("RESTIR_BIASED", 6), ("RESTIR_BIASED", 30),
                                       ("PATH", 3)])
def test02_a_frame_abandoned_for_an_edit_keeps_the_twin(vp, recorder, monkeypatch, mode, nth):
    """The leader abandons a frame at its nth interrupt poll (the first
    pass, the middle of the frame, shading): the twin unwinds it too and is
    kept, and the frames that follow are bitwise those of a twin forked
    anew after the abandoned frame."""
    from restir_gi.core.workers import forked
    if not forked.AVAILABLE:
        pytest.skip("no fork on this platform")
    calls = _count_forks(monkeypatch, forked)
    kept = _frames(vp, recorder, True, monkeypatch, abandon_at=nth, mode=mode)
    assert calls["start"] == 1

    def ended(self, fingerprint, state):
        self.end()
        return False
    monkeypatch.setattr(forked.Twin, "abandon", ended)
    calls["start"] = 0
    anew = _frames(vp, recorder, True, monkeypatch, abandon_at=nth, mode=mode)
    assert calls["start"] == 2
    assert len(kept) == len(anew) == 7
    for i, (a, b) in enumerate(zip(kept, anew)):
        assert np.isfinite(a).all()
        assert np.array_equal(a, b), f"frame {i}"
