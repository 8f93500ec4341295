"""The extension in a real Blender window (tools/real_blender.py): installed
from the linux-x64 package into Blender 5.2 LTS (Python 3.14), picked in the
Render Engine dropdown, the viewport switched to Rendered, F12, the
Preferences' add-on entry, and ``blender -b FILE -E RESTIR_GI -a``.

Runs where the real Blender root exists (tools/real_blender_setup.sh) and
skips with the reason otherwise; ``make e2e`` runs it alone. Screenshots and
logs land in bench/out/e2e/.
"""

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import real_blender  # noqa: E402
from real_blender_driver import read_log  # noqa: E402

OUT = os.path.join(ROOT, "bench", "out", "e2e")
DRIVER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "window_driver.py")
BLEND = os.path.join(ROOT, "example_blends", "room_animated.blend")


def _package():
    """The linux-x64 package, built when missing."""
    found = sorted(p for p in os.listdir(os.path.join(ROOT, "dist")) if p.endswith("-linux_x64.zip")) \
        if os.path.isdir(os.path.join(ROOT, "dist")) else []
    if not found:
        subprocess.run([sys.executable, os.path.join(ROOT, "tools", "build_extension.py")], check=True,
                       stdout=subprocess.DEVNULL)
        found = sorted(p for p in os.listdir(os.path.join(ROOT, "dist")) if p.endswith("-linux_x64.zip"))
    return os.path.join(ROOT, "dist", found[-1])


@pytest.fixture(scope="module")
def session():
    reason = real_blender.missing()
    if reason:
        print(f"real-window tests skipped: {reason}")
        pytest.skip(reason)
    shutil.rmtree(OUT, ignore_errors=True)
    rc = real_blender.run(_package(), BLEND, DRIVER, OUT, [],
                          env={"REAL_RENDERED": "4", "REAL_MOVE": "10", "REAL_F12": "40"}, limit=420)
    with open(os.path.join(OUT, "blender.log"), errors="replace") as fh:
        log = fh.read()
    return rc, log, read_log(OUT)


def _image(path):
    """(H, W, 4) float32 of a PNG, row 0 at the bottom (read by Blender)."""
    import bpy
    img = bpy.data.images.load(path)
    try:
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        return px.reshape(h, w, 4)
    finally:
        bpy.data.images.remove(img)


def test_blender_ran_the_driver_to_the_end(session):
    rc, log, lines = session
    assert rc == 0, log[-3000:]
    assert "quitting" in lines, log[-3000:]
    assert "Traceback" not in log, log[-3000:]


def test_engine_in_the_dropdown_and_the_preferences(session):
    _, log, lines = session
    assert "RESTIR_GI" in lines["dropdown"][0].split(","), lines["dropdown"]
    assert lines["engine"] == ["RESTIR_GI"]
    assert lines["addon"][0].endswith(".restir_gi"), lines["addon"]
    assert os.path.isfile(os.path.join(OUT, "preferences.png"))


def test_viewport_shows_the_engines_image(session):
    """The 3D view after switching to Rendered differs from the Solid view
    and is no flat colour: the engine drew its frames."""
    _, log, lines = session
    x, y, w, h, _ = (int(v) for v in lines["area"][0].split())
    solid = _image(os.path.join(OUT, "solid.png"))[y:y + h, x:x + w, :3]
    rendered = _image(os.path.join(OUT, "rendered.png"))[y:y + h, x:x + w, :3]
    assert np.abs(rendered - solid).mean() > 0.05
    assert rendered.std() > 0.05


def test_viewport_follows_edits(session):
    """A camera turn and a moved object, made from a timer while Rendered
    refines: a frame that includes both is published, and the 3D view is
    drawn again with it (the draws come from redraw.py's watcher, not from
    view_draw tagging itself)."""
    _, _, lines = session
    seconds, name, frames, included = lines["motion"][0].split()
    assert included == "True", lines["motion"]
    assert float(seconds) < 25 and int(frames) >= 1
    x, y, w, h, _ = (int(v) for v in lines["area"][0].split())
    before = _image(os.path.join(OUT, "before_move.png"))[y:y + h, x:x + w, :3]
    after = _image(os.path.join(OUT, "after_move.png"))[y:y + h, x:x + w, :3]
    assert np.abs(after - before).mean() > 0.01        # the view turned
    assert after.std() > 0.05                          # and shows an image, not a flat colour


def test_f12_writes_the_image(session):
    _, _, lines = session
    seconds, written = lines["f12"][0].split()
    assert written == "True"
    img = _image(os.path.join(OUT, "f12.png"))
    assert img.shape[:2] == (180, 320)
    assert 0.02 < img[..., :3].mean() < 0.98


def test_headless_animation_render(session):
    """``blender -b FILE -E RESTIR_GI -s 1 -e 3 -a`` writes three frames."""
    _, _, lines = session
    rc, seconds, frames = lines["batch"][0].split()
    assert rc == "0", open(os.path.join(OUT, "batch.log")).read()[-3000:]
    assert frames.split(",") == ["anim_0001.png", "anim_0002.png", "anim_0003.png"]
    for name in frames.split(","):
        assert _image(os.path.join(OUT, name))[..., :3].mean() > 0.02


def test_headless_chunk_render_warms_up(session):
    """``blender -b FILE -E RESTIR_GI -s 3 -e 3 -a`` (a farm's chunk: -s
    moves the scene's frame_start after the file is loaded) renders the
    chunk warm-up's frames 1 and 2 and writes frame 3 only."""
    _, _, lines = session
    rc, frames, warmed = lines["chunk"][0].split()
    assert rc == "0", open(os.path.join(OUT, "chunk.log")).read()[-3000:]
    assert frames == "chunk_0003.png" and warmed == "1,2", lines["chunk"]
    assert _image(os.path.join(OUT, frames))[..., :3].mean() > 0.02


def test_material_preview_is_rendered_by_the_engine(session):
    """The material's preview icon in the Properties editor's slot list
    holds an image (engines without bl_use_preview leave it empty)."""
    _, _, lines = session
    size, mean = lines["preview"][0].split()
    assert size != "0x0" and float(mean) > 0.02, lines["preview"]
