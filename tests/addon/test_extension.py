"""The extension packages: build, validate, contents, install, headless render.

`make build` writes one package per platform of the manifest (Blender's
``blender_ext.py build --split-platforms``), each holding the embreex and
OpenEXR wheels of its own platform for every Python Blender runs on (3.11:
Blender 4.2 LTS to 5.0; 3.13: 5.1 and 5.2 LTS; 3.14: Linux distributions'
builds), and a copy of this machine's package under the plain name
``<id>-<version>.zip``, which the install and render tests use.

Everything that needs a fresh Blender (BLENDER_USER_RESOURCES is read when bpy
is imported) runs in a subprocess of the same Python.
"""

import glob
import hashlib
import importlib.util
import json
import os
import subprocess
import sys
import textwrap
import tomllib
import zipfile

import pytest

pytestmark = pytest.mark.slow      # renders through whole Blender processes

REPO_ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
TOOLS = os.path.join(REPO_ROOT, "tools")

with open(os.path.join(REPO_ROOT, "blender_manifest.toml"), "rb") as _fh:
    MANIFEST = tomllib.load(_fh)
PKG_ID = MANIFEST["id"]
MODULE = "bl_ext.user_default." + PKG_ID
PLATFORMS = ("linux-x64", "macos-arm64", "macos-x64", "windows-x64")
# CPython of Blender 4.2 LTS to 5.0, of 5.1 and 5.2 LTS, and of Linux
# distributions' Blender built against their own Python (Debian's 5.2: 3.14).
PYTHONS = ("cp311", "cp313", "cp314")
DISTRIBUTIONS = ("embreex", "openexr")


def _load_build_extension():
    spec = importlib.util.spec_from_file_location("build_extension", os.path.join(TOOLS, "build_extension.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


build_extension = _load_build_extension()


def wheel_tags(path):
    """(distribution, python tag, abi tag, Blender platform) of a wheel file name."""
    parts = os.path.basename(path)[:-len(".whl")].split("-")
    platform_tag = parts[-1]
    if platform_tag.startswith("manylinux") and platform_tag.endswith("_x86_64"):
        platform = "linux-x64"
    elif platform_tag.startswith("macosx_") and platform_tag.endswith("_arm64"):
        platform = "macos-arm64"
    elif platform_tag.startswith("macosx_") and platform_tag.endswith("_x86_64"):
        platform = "macos-x64"
    elif platform_tag == "win_amd64":
        platform = "windows-x64"
    else:
        platform = platform_tag
    return parts[0].lower(), parts[-3], parts[-2], platform


def sha256_of(path):
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def run(cmd, timeout=600, env=None, cwd=REPO_ROOT):
    proc = subprocess.run(cmd, cwd=cwd, env=env, timeout=timeout,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.returncode == 0, "command failed ({}): {}\n{}".format(
        proc.returncode, " ".join(cmd), proc.stdout)
    return proc.stdout


def blender_env(user_resources):
    env = dict(os.environ)
    env["BLENDER_USER_RESOURCES"] = str(user_resources)
    return env


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Build the packages into a temporary folder (wheels are fetched into
    wheels/): {platform: its package, "host": this machine's package}."""
    out_dir = tmp_path_factory.mktemp("dist")
    stdout = run([sys.executable, os.path.join(TOOLS, "build_extension.py"),
                  "--output-dir", str(out_dir)])
    zip_path = stdout.strip().splitlines()[-1]
    assert zip_path == str(out_dir / "{}-{}.zip".format(PKG_ID, MANIFEST["version"]))
    assert os.path.isfile(zip_path)
    packages = {"host": zip_path}
    for platform in PLATFORMS:
        packages[platform] = str(out_dir / "{}-{}-{}.zip".format(
            PKG_ID, MANIFEST["version"], platform.replace("-", "_")))
        assert os.path.isfile(packages[platform]), stdout
    assert sorted(os.listdir(out_dir)) == sorted(os.path.basename(p) for p in packages.values())
    return packages


@pytest.fixture(scope="module")
def built_zip(built):
    """The package of this machine, as tools/render.py and the farm install it."""
    return built["host"]


def find_blender_ext():
    spec = importlib.util.find_spec("bpy")
    found = []
    for location in spec.submodule_search_locations:
        found += glob.glob(os.path.join(location, "*", "scripts", "addons_core", "bl_pkg",
                                        "cli", "blender_ext.py"))
    assert found, "blender_ext.py not found in the bpy module"
    return sorted(found)[-1]


def test_manifest_fields():
    assert MANIFEST["schema_version"] == "1.0.0"
    assert MANIFEST["id"] == "restir_gi" and MANIFEST["id"].isidentifier()
    assert MANIFEST["type"] == "add-on"
    assert MANIFEST["blender_version_min"] == "4.2.0"
    assert not MANIFEST["tagline"].endswith((".", "!", "?", ",", ";", ":"))
    assert tuple(MANIFEST["platforms"]) == PLATFORMS
    for wheel in MANIFEST["wheels"]:
        assert wheel.startswith("./wheels/") and wheel.endswith(".whl")


def test_manifest_lists_every_platform_and_python_once():
    """One wheel of each distribution per platform and Python, and no other."""
    tags = [wheel_tags(w) for w in MANIFEST["wheels"]]
    assert len(set(MANIFEST["wheels"])) == len(MANIFEST["wheels"])
    for dist, python, abi, platform in tags:
        assert python == abi, (dist, python, abi)      # CPython's own ABI, no abi3, no free-threaded
    assert sorted((d, py, p) for d, py, _, p in tags) == sorted(
        (d, py, p) for d in DISTRIBUTIONS for py in PYTHONS for p in PLATFORMS)
    versions = {os.path.basename(w).split("-")[1] for w in MANIFEST["wheels"]
                if os.path.basename(w).startswith("embreex-")}
    assert versions == {"4.4.0.post1"}
    versions = {os.path.basename(w).split("-")[1] for w in MANIFEST["wheels"]
                if os.path.basename(w).lower().startswith("openexr-")}
    assert versions == {"3.5.3"}


def test_every_wheel_exists_and_matches_its_hash(built):
    """The build fetched every wheel of the manifest, each with the SHA-256
    PyPI publishes for it (tools/build_extension.py, WHEEL_SHA256)."""
    names = {os.path.basename(w) for w in MANIFEST["wheels"]}
    assert set(build_extension.WHEEL_SHA256) == names
    for wheel in MANIFEST["wheels"]:
        path = os.path.join(REPO_ROOT, wheel)
        assert os.path.isfile(path), wheel
        assert sha256_of(path) == build_extension.WHEEL_SHA256[os.path.basename(wheel)], wheel


@pytest.mark.parametrize("platform", PLATFORMS)
def test_platform_package_holds_its_own_wheels_only(built, platform):
    with zipfile.ZipFile(built[platform]) as zf:
        names = zf.namelist()
        manifest = tomllib.loads(zf.read("blender_manifest.toml").decode())
    wheels = sorted(n for n in names if n.startswith("wheels/"))
    expected = sorted(w[len("./"):] for w in MANIFEST["wheels"] if wheel_tags(w)[3] == platform)
    assert wheels == expected
    assert sorted((d, py) for d, py, _, p in map(wheel_tags, wheels)) == sorted(
        (d, py) for d in DISTRIBUTIONS for py in PYTHONS)
    assert {wheel_tags(w)[3] for w in wheels} == {platform}
    # The builder declares the package's platform (what Blender and the
    # extensions site read) and its wheels.
    generated = manifest["build"]["generated"]
    assert generated["platforms"] == [platform]
    assert sorted(w[len("./"):] for w in generated["wheels"]) == expected


def test_host_package_is_this_machines_platform_package(built):
    host = build_extension.host_platform()
    assert host in PLATFORMS, host
    with open(built["host"], "rb") as a, open(built[host], "rb") as b:
        assert a.read() == b.read()


@pytest.mark.parametrize("platform", PLATFORMS)
def test_package_validates(built, platform):
    stdout = run([sys.executable, find_blender_ext(), "validate", built[platform]])
    assert "Success" in stdout


def test_package_contents(built_zip):
    with zipfile.ZipFile(built_zip) as zf:
        names = zf.namelist()
    tops = {name.split("/", 1)[0] for name in names}

    assert "blender_manifest.toml" in names
    assert "__init__.py" in names
    assert "restir_addon/__init__.py" in names
    assert any(n.startswith("core/") and n.endswith(".py") for n in names)

    for excluded in ("tests", "example_blends", "bench", "docs", "tools", "farm", "out", "build",
                     "dist", ".venv", ".venv-py311", ".git", ".gitignore", ".ci",
                     ".blender_user", ".blender_user-py311", "Makefile", "pyproject.toml",
                     "requirements.txt", "requirements-py311.txt"):
        assert excluded not in tops, excluded
    assert not [n for n in names if "__pycache__" in n or n.endswith((".pyc", ".blend", ".blend1"))]


# Runs in a fresh interpreter: argv[1] = package zip, argv[2] = output image.
INSTALL_AND_RENDER = textwrap.dedent(r'''
    import json, os, sys
    user = os.environ["BLENDER_USER_RESOURCES"]
    # Blender puts the unpacked wheels ahead of site-packages (when the folder
    # exists at start-up): do it now, so the bundled wheels are the ones used.
    site = os.path.join(user, "extensions", ".local", "lib",
                        "python%d.%d" % sys.version_info[:2], "site-packages")
    os.makedirs(site, exist_ok=True)
    sys.path.insert(0, site)
    import bpy

    zip_path, image_path, module = sys.argv[1], sys.argv[2], sys.argv[3]
    assert bpy.utils.user_resource("EXTENSIONS").startswith(user)
    result = bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True)
    assert result == {"FINISHED"}, result
    assert module in bpy.context.preferences.addons, list(bpy.context.preferences.addons.keys())

    engines = [c for c in bpy.types.RenderEngine.__subclasses__()
               if getattr(c, "bl_idname", None) == "RESTIR_GI"]
    assert len(engines) == 1, engines

    import embreex, OpenEXR
    scene = bpy.context.scene
    scene.render.engine = "RESTIR_GI"
    assert scene.render.engine == "RESTIR_GI"
    scene.restir_gi.samples = 1
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    scene.render.resolution_percentage = 100
    settings = scene.render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"
    settings.color_depth = "32"
    scene.render.use_file_extension = False
    scene.render.filepath = image_path
    result = bpy.ops.render.render(write_still=True)
    assert result == {"FINISHED"}, result
    print("RESULT " + json.dumps({
        "engine_module": engines[0].__module__,
        "addon_file": sys.modules[module].__file__,
        "embreex": embreex.__file__,
        "openexr": OpenEXR.__file__,
    }))
''')


def test_install_enable_and_render(built_zip, tmp_path):
    user = tmp_path / "blender_user"
    image = tmp_path / "frame.exr"
    # Run outside the repository (and -P: no working directory on sys.path), so
    # nothing can be imported from the source tree by accident.
    stdout = run([sys.executable, "-P", "-c", INSTALL_AND_RENDER, built_zip, str(image), MODULE],
                 env=blender_env(user), cwd=tmp_path)
    result = json.loads([ln for ln in stdout.splitlines() if ln.startswith("RESULT ")][-1][7:])

    installed = os.path.realpath(user / "extensions" / "user_default" / PKG_ID)
    assert result["engine_module"].startswith(MODULE + ".")
    assert os.path.realpath(result["addon_file"]).startswith(installed + os.sep)
    # The bundled wheels were unpacked and are the copies in use.
    for key in ("embreex", "openexr"):
        assert os.path.realpath(result[key]).startswith(os.path.realpath(user) + os.sep), result[key]

    import OpenEXR
    parts = OpenEXR.File(str(image)).parts
    combined = [p for p in parts if p.name().endswith("Combined")]
    assert combined, [p.name() for p in parts]
    pixels = next(iter(combined[0].channels.values())).pixels
    assert pixels.shape == (24, 32, 4)
    assert str(pixels.dtype) == "float32"


def make_tiny_animation(path, env):
    code = textwrap.dedent(r'''
        import sys, bpy
        scene = bpy.context.scene
        scene.render.resolution_x, scene.render.resolution_y = 32, 24
        scene.render.resolution_percentage = 100
        scene.frame_start, scene.frame_end = 1, 2
        cube = bpy.data.objects["Cube"]
        cube.location = (0, 0, 0); cube.keyframe_insert("location", frame=1)
        cube.location = (0.5, 0, 0); cube.keyframe_insert("location", frame=2)
        bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
    ''')
    run([sys.executable, "-P", "-c", code, str(path)], env=env, cwd=path.parent)


def test_render_tool_writes_exr_and_png_per_frame(built_zip, tmp_path):
    user = tmp_path / "blender_user"
    blend = tmp_path / "tiny.blend"
    out = tmp_path / "out"
    make_tiny_animation(blend, blender_env(tmp_path / "scratch_user"))

    stdout = run([sys.executable, os.path.join(TOOLS, "render.py"), str(blend),
                  "--output", str(out), "--samples", "1",
                  "--package", built_zip, "--user-resources", str(user)], cwd=tmp_path)
    assert "frame 1 (1/2)" in stdout and "frame 2 (2/2)" in stdout
    assert sorted(os.listdir(out)) == ["frame_0001.exr", "frame_0001.png",
                                       "frame_0002.exr", "frame_0002.png"]

    import OpenEXR
    for frame in (1, 2):
        parts = OpenEXR.File(str(out / "frame_{:04d}.exr".format(frame))).parts
        combined = [p for p in parts if p.name().endswith("Combined")]
        assert combined, [p.name() for p in parts]
        pixels = next(iter(combined[0].channels.values())).pixels
        assert pixels.shape == (24, 32, 4) and str(pixels.dtype) == "float32"
        with open(out / "frame_{:04d}.png".format(frame), "rb") as fh:
            head = fh.read(24)
        assert head[:8] == b"\x89PNG\r\n\x1a\n"
        assert int.from_bytes(head[16:20], "big") == 32 and int.from_bytes(head[20:24], "big") == 24

    # A second run reuses the installed copy (no reinstall) and --frame renders one frame.
    out_single = tmp_path / "single"
    stdout = run([sys.executable, os.path.join(TOOLS, "render.py"), str(blend),
                  "--output", str(out_single), "--frame", "2", "--samples", "1",
                  "--package", built_zip, "--user-resources", str(user)], cwd=tmp_path)
    assert "installing" not in stdout
    assert sorted(os.listdir(out_single)) == ["frame_0002.exr", "frame_0002.png"]


def test_render_tool_missing_blend(tmp_path):
    proc = subprocess.run([sys.executable, os.path.join(TOOLS, "render.py"),
                           str(tmp_path / "missing.blend")],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=60)
    assert proc.returncode == 2
    assert "blend file not found" in proc.stderr
