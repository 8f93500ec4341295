"""restir_addon/viewport/redraw.py: the rendered viewport is drawn again when
its session has news (a new frame, a new status), not on every pass of the
event loop."""

from types import SimpleNamespace

import pytest


class FakeSession:
    def __init__(self):
        self.frame_serial = 0
        self.text = "Moving"

    def status(self):
        return self.text


@pytest.fixture
def redraw(addon):
    return addon.restir_addon.viewport.redraw


def test01_tags_only_on_news(redraw):
    tags = []
    r = redraw.Redraws(tag=lambda: tags.append(1))
    s = FakeSession()
    r.watch(s)
    assert r.tick() == redraw.INTERVAL and len(tags) == 1       # never drawn: news
    r.drawn(s, s.frame_serial, s.status())
    for _ in range(3):
        r.tick()
    assert len(tags) == 1                                        # nothing new: no redraw
    s.frame_serial += 1
    r.tick()
    assert len(tags) == 2                                        # a new frame
    r.drawn(s, s.frame_serial, s.status())
    s.text = "Done"
    r.tick()
    assert len(tags) == 3                                        # a new status
    r.drawn(s, s.frame_serial, s.status())
    r.watch(s)                                                   # idempotent: keeps what was drawn
    r.tick()
    assert len(tags) == 3 and len(r) == 1
    r.forget(s)
    assert r.tick() is None and len(r) == 0                      # the timer stops


def test02_a_frame_published_during_the_draw_is_news(redraw):
    """view_draw reads the serial before it draws and the status after: a
    frame published in between still gets its own redraw."""
    tags = []
    r = redraw.Redraws(tag=lambda: tags.append(1))
    s = FakeSession()
    r.watch(s)
    serial = s.frame_serial
    s.frame_serial += 1
    r.drawn(s, serial, s.status())
    r.tick()
    assert tags == [1]


def test03_a_failing_tag_keeps_the_timer(redraw, capsys):
    def tag():
        raise RuntimeError("no window")
    r = redraw.Redraws(tag=tag)
    r.watch(FakeSession())
    assert r.tick() == redraw.INTERVAL
    assert "no window" in capsys.readouterr().err


def test04_view_draw_marks_what_it_drew(vp_draw, redraw, monkeypatch):
    """view_draw no longer tags its own redraw; it tells the watcher what it
    showed, and free() stops watching."""
    import bpy
    s = FakeSession()
    s.frame = None
    s.configure = s.resize = s.set_view = s.close = lambda *a, **k: None
    calls = []
    engine = SimpleNamespace(viewport_session=s, tag_redraw=lambda: calls.append("redraw"),
                             update_stats=lambda a, b: calls.append(b))
    monkeypatch.setattr(vp_draw, "session_settings", lambda scene: {})
    monkeypatch.setattr(vp_draw, "camera_from_region", lambda region_data, scene: None)
    redraw.REDRAWS.watch(s)
    try:
        context = SimpleNamespace(region=SimpleNamespace(width=4, height=3), region_data=None)
        vp_draw.view_draw(engine, context, SimpleNamespace(scene=bpy.context.scene))
        assert calls == ["ReSTIR GI | Moving"]
        assert not redraw.news(s, redraw.REDRAWS._sessions[id(s)][1])
        s.frame_serial += 1
        assert redraw.news(s, redraw.REDRAWS._sessions[id(s)][1])
        vp_draw.free(engine)
        assert id(s) not in redraw.REDRAWS._sessions and engine.viewport_session is None
    finally:
        redraw.REDRAWS.forget(s)
