"""The extension package: build, validate, contents, install, headless render.

Everything that needs a fresh Blender (BLENDER_USER_RESOURCES is read when bpy
is imported) runs in a subprocess of the same Python.
"""

import glob
import json
import os
import subprocess
import sys
import textwrap
import tomllib
import zipfile

import pytest

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOOLS = os.path.join(REPO_ROOT, "tools")

with open(os.path.join(REPO_ROOT, "blender_manifest.toml"), "rb") as _fh:
    MANIFEST = tomllib.load(_fh)
PKG_ID = MANIFEST["id"]
MODULE = "bl_ext.user_default." + PKG_ID


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
def built_zip(tmp_path_factory):
    """Build the package into a temporary folder (wheels are fetched into wheels/)."""
    out_dir = tmp_path_factory.mktemp("dist")
    stdout = run([sys.executable, os.path.join(TOOLS, "build_extension.py"),
                  "--output-dir", str(out_dir)])
    zip_path = stdout.strip().splitlines()[-1]
    assert zip_path == str(out_dir / "{}-{}.zip".format(PKG_ID, MANIFEST["version"]))
    assert os.path.isfile(zip_path)
    return zip_path


def find_blender_ext():
    import importlib.util
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
    for wheel in MANIFEST["wheels"]:
        assert wheel.startswith("./wheels/") and wheel.endswith(".whl")
        assert "-cp311-cp311-" in wheel


def test_package_validates(built_zip):
    stdout = run([sys.executable, find_blender_ext(), "validate", built_zip])
    assert "Success" in stdout


def test_package_contents(built_zip):
    with zipfile.ZipFile(built_zip) as zf:
        names = zf.namelist()
    tops = {name.split("/", 1)[0] for name in names}

    assert "blender_manifest.toml" in names
    assert "__init__.py" in names
    assert "restir_addon/__init__.py" in names
    assert any(n.startswith("core/") and n.endswith(".py") for n in names)
    for wheel in MANIFEST["wheels"]:
        assert wheel[len("./"):] in names, wheel
    assert len([n for n in names if n.startswith("wheels/")]) == len(MANIFEST["wheels"])

    for excluded in ("tests", "example_blends", "bench", "docs", "tools", "out", "build",
                     "dist", ".venv", ".git", ".gitignore", ".ci", ".blender_user",
                     "Makefile", "requirements.txt"):
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
