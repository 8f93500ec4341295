"""When the rendered viewport is drawn again: when its session has something
new to show, not on every pass of Blender's event loop.

A view_draw that tags its own redraw makes Blender draw the region again at
once, as fast as it can, for as long as the image is not finished. Each of
those draws runs the add-on's Python on the main thread and draws the region
through the display transform; on a machine whose OpenGL is in software,
the draws took the cores from the render thread (a full-size frame of the
example room took 3x its headless time in a real window;
bench/viewport_window.py). Cycles' viewport is drawn when its session has a
new frame. Here a timer on Blender's main thread looks at the live sessions
every INTERVAL seconds and tags the rendered 3D views for a redraw when one
of them published a frame or changed its status text since it was drawn.

``Redraws`` holds the sessions (plain objects, no Blender data, so nothing
freed by Blender is touched from the timer); ``draw.py`` marks what it drew
and adds and removes sessions.
"""

import traceback

import bpy

INTERVAL = 0.02     # seconds between looks: well under a frame's time, a 50 Hz poll of a few attributes


def news(session, drawn):
    """Whether ``session`` has something its last draw (``drawn``: the
    (frame serial, status) it showed, None if never) did not show."""
    return drawn != (session.frame_serial, session.status())


class Redraws:
    """The viewport sessions a timer watches for news (see the module's
    docstring). ``tag`` is what a tick calls when one has news: by default
    it tags every 3D view in Rendered shading for a redraw (which one a
    session draws into is Blender's to know)."""

    def __init__(self, tag=None):
        self._sessions = {}          # id(session) -> [session, drawn]
        self._tag = tag or tag_rendered_views

    def __len__(self):
        return len(self._sessions)

    def watch(self, session):
        """Watch ``session`` (idempotent); starts the timer if it is not running."""
        self._sessions.setdefault(id(session), [session, None])
        if not bpy.app.background and not bpy.app.timers.is_registered(self.tick):
            bpy.app.timers.register(self.tick, first_interval=INTERVAL)

    def drawn(self, session, serial, status):
        """A view_draw has just shown ``session``'s frame ``serial`` and ``status``."""
        entry = self._sessions.get(id(session))
        if entry is not None:
            entry[1] = (serial, status)

    def forget(self, session):
        self._sessions.pop(id(session), None)

    def tick(self):
        """The timer: tag a redraw if any session has news; stops (returns
        None) when no session is left."""
        try:
            if any(news(s, drawn) for s, drawn in self._sessions.values()):
                self._tag()
        except Exception:   # noqa: BLE001 -- a timer that raises is dropped by Blender; keep polling
            traceback.print_exc()
        return INTERVAL if self._sessions else None


def tag_rendered_views():
    """Tag every 3D view whose shading is Rendered, in every window, for a redraw."""
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D" and getattr(area.spaces.active.shading, "type", "") == "RENDERED":
                area.tag_redraw()


REDRAWS = Redraws()
