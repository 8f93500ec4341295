"""The viewport's ReSTIR frames in two processes (core/workers/forked.py):
the twin is forked once and kept between frames while the view turns and an
object moves, a frame abandoned for an edit ends it, and the images are
bitwise those of two threads."""

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


def _frames(vp, recorder, twin, monkeypatch):
    import bpy
    monkeypatch.setattr(vp.ViewportSession, "twin_process", twin)
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED", samples=0, threads=2)
    session.resize(*SIZE)
    frames = []

    def render(n):
        for _ in range(n):
            assert session.render_step()
            frames.append(session.frame.copy())

    render(3)
    session.set_view(_turned(session.view, 2.0))
    render(2)
    mover = bpy.data.objects["Mover"]
    session.sync(bpy.context.evaluated_depsgraph_get(),
                 recorder.edit(lambda: setattr(mover, "location", (0.6, -0.4, 0.3))))
    render(2)
    assert session.render_size == SIZE
    session.close()
    return frames


def test01_frames_of_the_twin_are_those_of_threads_and_it_is_kept(vp, recorder, monkeypatch):
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
    threads = _frames(vp, recorder, False, monkeypatch)
    assert calls == {"start": 0, "resume": 0}
    twin = _frames(vp, recorder, True, monkeypatch)
    # One fork for the first frame; the six after it resume the parked twin
    # (the object's move is sent as a ScenePatch) or fork again at most once.
    assert calls["start"] <= 2 and calls["resume"] >= 5, calls
    assert len(twin) == len(threads) == 7
    for i, (a, b) in enumerate(zip(twin, threads)):
        assert np.isfinite(a).all()
        assert np.array_equal(a, b), f"frame {i}"
