"""tools/farm.py: an animation rendered in chunks on a Dask LocalCluster of two
workers, each chunk through tools/render.py (the installed extension) with
the engine's chunk warm-up.

- Every frame is written exactly once, complete and readable, and the first
  frame of a chunk is the same frame of one continuous render (its warm-up
  reaches back to the first frame: same pixels; MSE against a 1024-spp
  Cycles reference within 10 %), unlike a cold start of the chunk. That a
  warm-up which does not reach back is statistically as good is shown on a
  longer animation in tests/addon/test_addon_chunks.py.
- A render process killed during a chunk: the chunk is retried and only its
  missing frames are rendered; nothing is truncated or written twice.
- Bad input: a clear message, exit status 2, nothing written.
- A configuration error (no package built yet, a package for another
  platform or Python, a workers' Python without bpy, ...) fails once, before
  any task is submitted, saying what to do; a chunk whose render refuses its
  configuration on a worker stops the farm instead of being retried.

The example animation (example_blends/room_animated.blend) is rendered at
30 % of its resolution and over 18 frames to keep the suite short.
"""

import os
import platform
import re
import shutil
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

pytestmark = pytest.mark.slow      # renders through whole Blender processes

REPO_ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
TOOLS = os.path.join(REPO_ROOT, "tools")
EXAMPLE = os.path.join(REPO_ROOT, "example_blends", "room_animated.blend")
FRAMES = range(1, 19)
CHUNK = 6
STARTS = (7, 13)    # with the file's 16 warm-up frames both chunks reach back to frame 1


def run(cmd, timeout=900, **kw):
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=timeout, **kw)


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """(small copy of the example animation, built package, Blender user folder)."""
    tmp = tmp_path_factory.mktemp("farm")
    blend = tmp / "room_small.blend"
    code = textwrap.dedent(r'''
        import sys, bpy
        bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
        scene = bpy.context.scene
        scene.render.resolution_percentage = 30
        scene.frame_start, scene.frame_end = 1, 18
        bpy.ops.wm.save_as_mainfile(filepath=sys.argv[2])
    ''')
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp / "scratch_user"))
    proc = run([sys.executable, "-c", code, EXAMPLE, str(blend)], env=env)
    assert proc.returncode == 0 and blend.is_file(), proc.stdout
    dist = tmp / "dist"
    proc = run([sys.executable, os.path.join(TOOLS, "build_extension.py"), "--output-dir", str(dist)])
    assert proc.returncode == 0, proc.stdout
    package = proc.stdout.strip().splitlines()[-1]
    return blend, package, tmp / "blender_user"


def farm(setup, out, *extra, timeout=900, wait=True):
    blend, package, user = setup
    cmd = [sys.executable, os.path.join(TOOLS, "farm.py"), str(blend), "--frames",
           f"{FRAMES[0]}-{FRAMES[-1]}", "--chunk", str(CHUNK), "--out", str(out), "--workers", "2",
           "--package", package, "--user-resources", str(user), *extra]
    if not wait:
        return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return run(cmd, timeout=timeout)


def render(setup, out, first, last, *extra):
    blend, package, user = setup
    proc = run([sys.executable, os.path.join(TOOLS, "render.py"), str(blend), "--frames",
                f"{first}-{last}", "--output", str(out), "--package", package,
                "--user-resources", str(user), *extra])
    assert proc.returncode == 0, proc.stdout
    return proc.stdout


def combined(path):
    from restir_gi.core.camera.film import read_exr
    return read_exr(path)


def assert_all_frames(out):
    names = sorted(n for n in os.listdir(out) if not n.startswith("."))
    assert names == sorted(f"frame_{f:04d}.{e}" for f in FRAMES for e in ("exr", "png")), names
    for f in FRAMES:
        img = combined(out / f"frame_{f:04d}.exr")
        assert np.isfinite(img).all() and img.mean() > 0, f
    assert not os.listdir(out / ".partial") if (out / ".partial").exists() else True


def cycles_reference(blend, frames, spp=1024):
    """Cycles at ``spp`` of the given frames (same bounces as the file's ReSTIR
    settings), rendered in this process."""
    import bpy
    from restir_gi.core.camera.film import read_exr
    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    scene = bpy.context.scene
    bounces = scene.restir_gi.max_bounces if hasattr(scene, "restir_gi") else 2
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.seed = "CPU", spp, 7
    c.use_denoising = c.use_adaptive_sampling = False
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = bounces
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    refs = {}
    for f in frames:
        scene.frame_set(f)
        path = os.path.join(os.path.dirname(str(blend)), f"ref_{f}.exr")
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True)
        refs[f] = read_exr(path)[..., :3]
    return refs


def mse(a, b):
    return float(((a - b) ** 2).mean())


def test_chunks_on_two_workers_match_the_continuous_render(addon, setup, tmp_path):
    blend = setup[0]
    proc = farm(setup, tmp_path / "chunks")
    assert proc.returncode == 0, proc.stdout
    assert_all_frames(tmp_path / "chunks")
    summary = re.search(r"summary: 18 frames, (\d+) rendered .* (\d+) retries, (\d+) failed", proc.stdout)
    assert summary and summary.groups() == ("18", "0", "0"), proc.stdout
    workers = set(re.findall(r"done on (tcp://\S+)", proc.stdout))
    assert len(workers) == 2, proc.stdout          # both workers took chunks

    render(setup, tmp_path / "continuous", FRAMES[0], FRAMES[-1])
    cold = tmp_path / "cold"
    for start in STARTS:
        render(setup, cold, start, start, "--chunk-warmup", "0")
    refs = cycles_reference(blend, STARTS)
    for f in STARTS:
        chunk = combined(tmp_path / "chunks" / f"frame_{f:04d}.exr")
        cont = combined(tmp_path / "continuous" / f"frame_{f:04d}.exr")
        first_cold = combined(cold / f"frame_{f:04d}.exr")
        e_chunk, e_cont, e_cold = (mse(img, refs[f]) for img in (chunk, cont, first_cold))
        print(f"frame {f}: MSE chunk {e_chunk:.5f}, continuous {e_cont:.5f}, cold {e_cold:.5f}")
        assert abs(e_chunk / e_cont - 1) < 0.10, (f, e_chunk, e_cont)
        assert np.abs(chunk - cont).mean() < 1e-3 * cont.mean(), f
        assert np.abs(first_cold - cont).mean() > 1e-2 * cont.mean(), f


def test_a_killed_render_is_retried_without_losing_or_repeating_frames(setup, tmp_path):
    import psutil
    out = tmp_path / "killed"
    proc = farm(setup, out, "--chunk-warmup", "0", "--retries", "2", wait=False)
    victim = None
    deadline = time.time() + 600
    while victim is None and time.time() < deadline and proc.poll() is None:
        # The chunk 7-12 render, once it has written its first frame.
        for p in psutil.process_iter(["cmdline"]):
            cmd = p.info["cmdline"] or []
            if "render.py" in " ".join(cmd) and "7-12" in cmd and (out / "frame_0007.png").exists():
                victim = p
                break
        time.sleep(0.05)
    assert victim is not None, "the render of chunk 7-12 was not seen"
    victim.kill()
    stdout, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, stdout
    assert "killed by signal 9" in stdout and "retry 1 of 2" in stdout, stdout
    assert_all_frames(out)
    # Every frame written once: 18 in all, over the killed attempt and its retry.
    written = re.search(r"summary: 18 frames, (\d+) rendered", stdout)
    assert written and written.group(1) == "18", stdout


@pytest.mark.parametrize("case", ["missing blend", "empty range", "chunk 0", "no scheduler"])
def test_bad_input_is_refused_and_writes_nothing(tmp_path, case):
    out = tmp_path / "out"
    args = {"missing blend": [str(tmp_path / "missing.blend"), "--frames", "1-4", "--chunk", "2"],
            "empty range": [EXAMPLE, "--frames", "5-3", "--chunk", "2"],
            "chunk 0": [EXAMPLE, "--frames", "1-4", "--chunk", "0"],
            "no scheduler": [EXAMPLE, "--frames", "1-4", "--chunk", "2",
                             "--scheduler", "tcp://127.0.0.1:9", "--timeout", "2"]}[case]
    proc = run([sys.executable, os.path.join(TOOLS, "farm.py"), *args, "--out", str(out)], timeout=120)
    assert proc.returncode == 2, proc.stdout
    message = {"missing blend": "blend file not found", "empty range": "--frames",
               "chunk 0": "--chunk must be at least 1", "no scheduler": "cannot reach"}[case]
    assert "error" in proc.stdout and message in proc.stdout, proc.stdout
    assert not out.exists()


def _fake_package(path, platforms, python_tag):
    """A zip with only a manifest, as a split package of the given platforms
    with wheels of one Python (what tools/farm.py reads of a package)."""
    import zipfile
    wheels = ", ".join(f'"./wheels/embreex-4.4.0.post1-{python_tag}-{python_tag}-{tag}.whl"'
                       for tag in ("manylinux_2_28_x86_64", "win_amd64"))
    manifest = (f'schema_version = "1.0.0"\nid = "restir_gi"\nversion = "0.1.0"\n'
                f'platforms = {platforms!r}\nwheels = [{wheels}]\n'.replace("'", '"'))
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("blender_manifest.toml", manifest)
    return path


def _this_platform():
    system = {"linux": "linux", "darwin": "macos", "win32": "windows"}.get(sys.platform, sys.platform)
    machine = platform.machine().lower()
    return f"{system}-{ {'x86_64': 'x64', 'amd64': 'x64', 'aarch64': 'arm64'}.get(machine, machine)}"


def _repo_copy(tmp_path):
    """The workers' repository as a fresh clone has it before `make build`:
    tools and manifest, no dist/."""
    repo = tmp_path / "repo"
    shutil.copytree(TOOLS, repo / "tools", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(os.path.join(REPO_ROOT, "blender_manifest.toml"), repo)
    return repo


HERE_PY = "cp{}{}".format(*sys.version_info[:2])
OTHER_PY = "cp313" if HERE_PY == "cp311" else "cp311"
OTHER_PLATFORM = "windows-x64" if _this_platform() != "windows-x64" else "linux-x64"


@pytest.mark.parametrize("case", ["no package built", "not a package", "package for another python",
                                  "package for another platform", "python without bpy",
                                  "no repository", "output is a file"])
def test_configuration_errors_fail_once_before_any_task(tmp_path, case):
    """Started before `make build` the farm used to submit every chunk, each
    failing 'extension package not found' until its retries ran out. Now
    every configuration error is found before a task is submitted (no
    cluster is started), and the message says what to do."""
    out = tmp_path / "out"
    repo = _repo_copy(tmp_path)
    good = _fake_package(tmp_path / "good.zip", [_this_platform()], HERE_PY)
    extra = {
        "no package built": [],
        "not a package": ["--package", str(tmp_path / "README.md")],
        "package for another python": ["--package", str(_fake_package(
            tmp_path / "other_py.zip", [_this_platform()], OTHER_PY))],
        "package for another platform": ["--package", str(_fake_package(
            tmp_path / "other_platform.zip", [OTHER_PLATFORM], HERE_PY))],
        "python without bpy": ["--package", str(good), "--worker-python", str(tmp_path / "python")],
        "no repository": ["--package", str(good)],
        "output is a file": ["--package", str(good)],
    }[case]
    (tmp_path / "README.md").write_text("not a zip")
    # A Python that runs but finds no bpy (-S: no site-packages).
    (tmp_path / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" -S "$@"\n')
    (tmp_path / "python").chmod(0o755)
    if case == "no repository":
        shutil.rmtree(repo / "tools")
    if case == "output is a file":
        out.write_text("")
    t0 = time.perf_counter()
    proc = run([sys.executable, os.path.join(TOOLS, "farm.py"), EXAMPLE, "--frames", "1-4",
                "--chunk", "2", "--out", str(out), "--worker-repo", str(repo), "--retries", "3", *extra],
               timeout=300)
    seconds = time.perf_counter() - t0
    print(proc.stdout)
    assert proc.returncode == 2, proc.stdout
    message = {
        "no package built": ["extension package not found", "make build"],
        "not a package": ["is not an extension package", "make build"],
        "package for another python": ["no wheels for Python {}.{}".format(*sys.version_info[:2]),
                                       "make build"],
        "package for another platform": [f"package for {OTHER_PLATFORM}", "not for this machine"],
        "python without bpy": ["has no bpy module", "make venv", "--worker-python"],
        "no repository": ["tools/render.py not found", "--worker-repo"],
        "output is a file": ["is a file, not a folder"],
    }[case]
    assert "error: configuration" in proc.stdout, proc.stdout
    for words in message:
        assert words in proc.stdout, (words, proc.stdout)
    # Once: no cluster, no chunk, no retry; nothing written.
    assert "chunks of up to" not in proc.stdout and "retry" not in proc.stdout, proc.stdout
    assert case == "output is a file" or not out.exists()
    assert seconds < 60, seconds


def test_a_chunk_refusing_its_configuration_is_not_retried(tmp_path):
    """A worker's render that exits with status 2 (render.py: bad arguments
    or a missing file, e.g. the package gone from a worker) stops the farm at
    once: retrying cannot mend it."""
    repo = _repo_copy(tmp_path)
    (repo / "tools" / "render.py").write_text(
        "import sys\nprint('[render] error: extension package not found: x.zip "
        "(build it with `make build`)', file=sys.stderr)\nsys.exit(2)\n")
    package = _fake_package(tmp_path / "good.zip", [_this_platform()], HERE_PY)
    out = tmp_path / "out"
    proc = run([sys.executable, os.path.join(TOOLS, "farm.py"), EXAMPLE, "--frames", "1-8",
                "--chunk", "2", "--out", str(out), "--workers", "2", "--retries", "3",
                "--worker-repo", str(repo), "--package", str(package)], timeout=300)
    print(proc.stdout)
    assert proc.returncode == 2, proc.stdout
    assert "stopped without retrying" in proc.stdout and "make build" in proc.stdout, proc.stdout
    assert "retry" not in proc.stdout.replace("without retrying", ""), proc.stdout
    # At most one failed attempt per worker (those already running), not 4 chunks x 4 tries.
    assert 1 <= proc.stdout.count(" failed: frames ") <= 2, proc.stdout


def test_frame_ranges():
    sys.path.insert(0, TOOLS)
    try:
        from frame_range import chunks, parse_range, runs
    finally:
        sys.path.remove(TOOLS)
    assert parse_range("1-24") == (1, 24) and parse_range("3..7") == (3, 7) and parse_range("5") == (5, 5)
    assert parse_range("-3--1") == (-3, -1) and parse_range("5-3") is None and parse_range("a-b") is None
    assert chunks(1, 18, 6) == [(1, 6), (7, 12), (13, 18)] and chunks(1, 5, 2)[-1] == (5, 5)
    assert runs([1, 2, 3, 5, 7, 8]) == [(1, 3), (5, 5), (7, 8)] and runs([1, 3, 5], 2) == [(1, 5)]
