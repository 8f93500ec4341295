"""bench/sweep.py, the robustness sweep over folders of .blend files: on two
tiny files made here (one renders; one has no camera, so the render operator
fails as it does when the engine reports an error) and a Git LFS pointer,
through a package built into a temporary folder."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.slow      # renders through whole Blender processes

REPO_ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SWEEP = os.path.join(REPO_ROOT, "bench", "sweep.py")
SWEEP_RENDER = os.path.join(REPO_ROOT, "bench", "sweep_render.py")


def run(cmd, cwd, env=None, timeout=600):
    return subprocess.run(cmd, cwd=cwd, env=env, timeout=timeout, text=True,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


@pytest.fixture(scope="module")
def blends(tmp_path_factory):
    """DIR with good.blend, sub/no_camera.blend and an LFS pointer; the package."""
    tmp = tmp_path_factory.mktemp("sweep")
    folder = tmp / "files"
    (folder / "sub").mkdir(parents=True)
    code = textwrap.dedent(r'''
        import sys, bpy
        scene = bpy.context.scene
        scene.render.resolution_x, scene.render.resolution_y = 320, 240
        bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
        bpy.data.objects.remove(bpy.data.objects["Camera"])
        bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
    ''')
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp / "scratch_user"))
    proc = run([sys.executable, "-P", "-c", code, str(folder / "good.blend"),
                str(folder / "sub" / "no_camera.blend")], cwd=tmp, env=env)
    assert proc.returncode == 0, proc.stdout
    (folder / "pointer.blend").write_text(
        "version https://git-lfs.github.com/spec/v1\noid sha256:0\nsize 1\n")
    proc = run([sys.executable, os.path.join(REPO_ROOT, "tools", "build_extension.py"),
                "--output-dir", str(tmp / "dist")], cwd=REPO_ROOT)
    assert proc.returncode == 0, proc.stdout
    return tmp, folder, proc.stdout.strip().splitlines()[-1]


def sweep(tmp, folder, package, *options):
    out = tmp / "report"
    proc = run([sys.executable, SWEEP, str(folder), "--size", "16x12", "--warmup", "2",
                "--samples", "1", "--output", str(out), "--package", package,
                "--user-resources", str(tmp / "user"), *options], cwd=tmp)
    with open(str(out) + ".json") as fh:
        data = json.load(fh)
    with open(str(out) + ".md") as fh:
        return proc, data, fh.read()


def test_sweep_reports_rendered_and_failed(blends):
    tmp, folder, package = blends
    proc, data, md = sweep(tmp, folder, package, "--modes", "path,biased")
    assert proc.returncode == 1, proc.stdout      # a failure: exit status 1
    results = {(e["file"], e["mode"]): e for e in data["results"]}
    assert sorted(results) == [("good.blend", "PATH"), ("good.blend", "RESTIR_BIASED"),
                               ("sub/no_camera.blend", "PATH"),
                               ("sub/no_camera.blend", "RESTIR_BIASED")]
    for mode in ("PATH", "RESTIR_BIASED"):
        good = results[("good.blend", mode)]
        assert good["status"] == "rendered" and good["bad_pixels"] == 0, good
        assert good["seconds"] > 0
        bad = results[("sub/no_camera.blend", mode)]
        assert bad["status"] == "failed", bad
        assert bad["error"] == "Cannot render, no camera"      # Blender's own report
    assert "| Path Tracing | 2 | 1 | 1 | 0 | 0 | 0 |" in md
    assert "| ReSTIR Biased | 2 | 1 | 1 | 0 | 0 | 0 |" in md
    assert "Skipped (not .blend files, e.g. Git LFS pointers): pointer.blend." in md
    # The report names the folder as DIR, never by its path.
    assert str(tmp) not in md and "python bench/sweep.py DIR --size 16x12" in md

    # --camera gives the file without one a camera, and it renders.
    proc, data, md = sweep(tmp, folder, package, "--modes", "unbiased", "--camera")
    assert proc.returncode == 0, proc.stdout
    assert [e["status"] for e in data["results"]] == ["rendered", "rendered"]
    assert data["results"][1]["camera"] == "added a camera"


def test_sweep_time_limit(blends):
    tmp, folder, package = blends
    proc, data, md = sweep(tmp, folder, package, "--modes", "path", "--limit", "1",
                           "--timeout", "0.5")
    assert proc.returncode == 1
    assert [(e["file"], e["status"]) for e in data["results"]] == [("good.blend", "timeout")]


def test_non_finite_pixels_counted_per_pass(tmp_path):
    import importlib.util

    import numpy as np
    import OpenEXR
    spec = importlib.util.spec_from_file_location("sweep_render", SWEEP_RENDER)
    render_tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(render_tool)

    combined = np.ones((3, 4), np.float32)
    depth = np.full((3, 4), 1e10, np.float32)
    combined[0, 1] = np.nan
    depth[0, 1] = np.inf            # the same pixel: counted once
    depth[2, 3] = -np.inf
    channels = {"View Layer.Combined.R": combined, "View Layer.Combined.G": combined.copy(),
                "View Layer.Depth.Z": depth}
    path = str(tmp_path / "passes.exr")
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 channels).write(path)
    assert render_tool.non_finite(path) == (1, 2, 2, {"View Layer.Combined": 1, "View Layer.Depth": 2})
