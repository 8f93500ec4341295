#!/usr/bin/env python3
"""Headless render through the installed ReSTIR GI extension.

The bpy-module equivalent of

    blender -b FILE.blend -E RESTIR_GI -a         (whole animation)
    blender -b FILE.blend -E RESTIR_GI -f N       (one frame, --frame N)

Usage:
    python tools/render.py FILE.blend [--frame N] [--output DIR] [--samples N]
                           [--package ZIP] [--user-resources DIR]

What it does:
1. Points ``BLENDER_USER_RESOURCES`` at ``<repo>/.blender_user`` (or
   --user-resources; before bpy is imported, since Blender reads it once at
   start-up), so nothing touches the user's own Blender configuration.
2. Installs the built package ``dist/restir_gi-<version>.zip`` (``make build``;
   or --package)
   into that folder's ``user_default`` extension repository, or reinstalls it
   when the zip is newer than the installed copy, otherwise just enables the
   installed add-on ``bl_ext.user_default.restir_gi``. The engine always comes
   from the installed package, never from the source tree, and its Python
   dependencies from the wheels bundled in the package.
3. Opens the .blend file, selects the RESTIR_GI engine and renders every frame
   of the scene's frame range (or only --frame N), writing for each frame
   ``DIR/frame_####.exr`` (multilayer OpenEXR, 32-bit float, linear, all
   passes) and ``DIR/frame_####.png`` (8-bit RGBA through the scene's view
   transform, as Blender writes a PNG). DIR defaults to ``<repo>/out/<blend
   name>``.

Progress (frame number, time per frame, files written) goes to stdout.
Exit status: 0 on success, 2 on bad arguments or missing files, 1 when the
render fails, the engine raises a Python exception (the render stops there;
Blender itself would print it and write an empty frame) or a frame file is
missing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tomllib

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REPO_MODULE = "user_default"
ENGINE_ID = "RESTIR_GI"


def log(msg: str) -> None:
    print("[render] " + msg, flush=True)


def show(path: str) -> str:
    """A path for messages: relative to the working directory when below it."""
    rel = os.path.relpath(path)
    return path if rel.startswith("..") else rel


def die(msg: str, code: int = 2) -> None:
    print("[render] error: " + msg, file=sys.stderr, flush=True)
    sys.exit(code)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description="Render a .blend file with the installed ReSTIR GI extension "
                    "(like `blender -b FILE.blend -E RESTIR_GI -a`), writing a 32-bit "
                    "multilayer EXR and a PNG per frame.")
    parser.add_argument("blend", help=".blend file to render")
    parser.add_argument("--frame", type=int, default=None,
                        help="render only this frame (like blender -f N); default: the whole frame range (-a)")
    parser.add_argument("--output", default=None,
                        help="output directory (default: <repo>/out/<blend name>)")
    parser.add_argument("--samples", type=int, default=None,
                        help="override scene.restir_gi.samples (samples per pixel per frame)")
    parser.add_argument("--package", default=None, metavar="ZIP",
                        help="extension package to install (default: <repo>/dist/<id>-<version>.zip)")
    parser.add_argument("--user-resources", default=os.path.join(REPO_ROOT, ".blender_user"),
                        metavar="DIR",
                        help="BLENDER_USER_RESOURCES folder the extension is installed into "
                             "(default: <repo>/.blender_user)")
    args = parser.parse_args(argv)
    if args.samples is not None and args.samples < 1:
        parser.error("--samples must be at least 1")
    return args


def extension_id_and_zip() -> tuple[str, str]:
    manifest_path = os.path.join(REPO_ROOT, "blender_manifest.toml")
    with open(manifest_path, "rb") as fh:
        manifest = tomllib.load(fh)
    pkg_id = manifest["id"]
    zip_path = os.path.join(REPO_ROOT, "dist", "{}-{}.zip".format(pkg_id, manifest["version"]))
    return pkg_id, zip_path


def extension_site_packages(user_resources: str) -> str:
    """Folder where Blender unpacks the wheels bundled with extensions."""
    return os.path.join(
        user_resources, "extensions", ".local", "lib",
        "python{}.{}".format(*sys.version_info[:2]), "site-packages")


def install_or_enable(bpy, pkg_id: str, zip_path: str, user_resources: str) -> str:
    """Make ``bl_ext.user_default.<pkg_id>`` enabled; returns the module name."""
    module = "bl_ext.{}.{}".format(REPO_MODULE, pkg_id)
    installed_dir = os.path.join(bpy.utils.user_resource('EXTENSIONS'), REPO_MODULE, pkg_id)
    installed_manifest = os.path.join(installed_dir, "blender_manifest.toml")
    if (not os.path.isfile(installed_manifest)
            or os.path.getmtime(zip_path) > os.path.getmtime(installed_manifest)):
        log("installing {} into {}".format(show(zip_path), show(user_resources)))
        result = bpy.ops.extensions.package_install_files(
            filepath=zip_path, repo=REPO_MODULE, enable_on_install=True)
        if result != {'FINISHED'}:
            die("installing {} failed: {}".format(zip_path, result), 1)
    if module not in bpy.context.preferences.addons:
        result = bpy.ops.preferences.addon_enable(module=module)
        if result != {'FINISHED'}:
            die("enabling {} failed: {}".format(module, result), 1)
    if module not in sys.modules or module not in bpy.context.preferences.addons:
        die("the add-on {} is not enabled after installation".format(module), 1)
    engines = [cls for cls in bpy.types.RenderEngine.__subclasses__()
               if getattr(cls, "bl_idname", None) == ENGINE_ID]
    if not engines:
        die("no render engine {} registered by {}".format(ENGINE_ID, module), 1)
    for cls in engines:
        if not cls.__module__.startswith(module + "."):
            die("render engine {} comes from {}, not from the installed {}".format(
                ENGINE_ID, cls.__module__, module), 1)
    return module


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)

    blend = os.path.abspath(args.blend)
    if not os.path.isfile(blend):
        die("blend file not found: {}".format(args.blend))
    pkg_id, zip_path = extension_id_and_zip()
    if args.package is not None:
        zip_path = os.path.abspath(args.package)
    if not os.path.isfile(zip_path):
        die("extension package not found: {} (build it with `make build`)".format(show(zip_path)))
    user_resources = os.path.abspath(args.user_resources)
    blend_name = os.path.splitext(os.path.basename(blend))[0]
    out_dir = os.path.abspath(args.output or os.path.join(REPO_ROOT, "out", blend_name))

    # Blender reads BLENDER_USER_RESOURCES once, when bpy is imported.
    os.environ["BLENDER_USER_RESOURCES"] = user_resources
    # Inside Blender, the bundled wheels are the only copies of the engine's
    # dependencies, and Blender puts their folder ahead of site-packages when it
    # exists at start-up. Do the same now (it may be created by the first
    # install only), so the engine always imports the wheels of the package and
    # not the copies in the environment running this script.
    site_packages = extension_site_packages(user_resources)
    os.makedirs(site_packages, exist_ok=True)
    sys.path.insert(0, site_packages)

    t_start = time.perf_counter()
    import bpy  # noqa: E402  (must follow the environment set-up above)

    module = install_or_enable(bpy, pkg_id, zip_path, user_resources)
    log("engine {} from {} ({})".format(ENGINE_ID, module, show(os.path.join(
        bpy.utils.user_resource('EXTENSIONS'), REPO_MODULE, pkg_id))))

    bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    scene = bpy.context.scene
    render = scene.render
    render.engine = ENGINE_ID
    if render.engine != ENGINE_ID:
        die("could not select the render engine {}".format(ENGINE_ID), 1)
    if args.samples is not None:
        scene.restir_gi.samples = args.samples

    if args.frame is not None:
        scene.frame_start = scene.frame_end = args.frame
    frames = list(range(scene.frame_start, scene.frame_end + 1, max(1, scene.frame_step)))

    os.makedirs(out_dir, exist_ok=True)
    render.filepath = os.path.join(out_dir, "frame_####")
    render.use_file_extension = True
    render.use_overwrite = True
    render.use_placeholder = False
    image_settings = render.image_settings
    image_settings.media_type = 'MULTI_LAYER_IMAGE'
    image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    image_settings.color_depth = '32'
    exr_settings = (image_settings.media_type, image_settings.file_format,
                    image_settings.color_depth, image_settings.color_mode)

    written: dict[int, list[str]] = {}
    frame_t0 = [0.0]

    def on_render_pre(scene, *_args):
        frame_t0[0] = time.perf_counter()

    def on_render_write(scene, *_args):
        # Called right after Blender wrote the EXR of this frame: save the same
        # Render Result again as a PNG, then restore the EXR settings for the
        # next frame.
        frame = scene.frame_current
        exr_path = scene.render.frame_path(frame=frame)
        settings = scene.render.image_settings
        settings.media_type = 'IMAGE'
        settings.file_format = 'PNG'
        settings.color_mode = 'RGBA'
        settings.color_depth = '8'
        try:
            png_path = scene.render.frame_path(frame=frame)
            bpy.data.images['Render Result'].save_render(png_path, scene=scene)
        finally:
            (settings.media_type, settings.file_format,
             settings.color_depth, settings.color_mode) = exr_settings
        written[frame] = [exr_path, png_path]
        log("frame {} ({}/{}): {:.2f} s -> {}, {}".format(
            frame, len(written), len(frames), time.perf_counter() - frame_t0[0],
            show(exr_path), show(png_path)))

    # Blender prints a Python exception raised by the engine (or by a handler)
    # and carries on with an empty frame; writing that empty frame as a
    # multilayer EXR even crashes bpy 5.0.1 (segmentation fault). Stop at the
    # first error instead, with the traceback and a clear exit status.
    default_excepthook = sys.excepthook

    def excepthook(exc_type, exc, tb):
        default_excepthook(exc_type, exc, tb)
        print("[render] error: Python exception while rendering frame {} (traceback above): "
              "{}: {}".format(bpy.context.scene.frame_current, exc_type.__name__, exc),
              file=sys.stderr, flush=True)
        sys.stdout.flush()
        os._exit(1)

    bpy.app.handlers.render_pre.append(on_render_pre)
    bpy.app.handlers.render_write.append(on_render_write)

    log("rendering {} ({} frame{} {}..{}, {}x{} at {}%) into {}".format(
        show(blend), len(frames), "" if len(frames) == 1 else "s",
        frames[0] if frames else "-", frames[-1] if frames else "-",
        render.resolution_x, render.resolution_y, render.resolution_percentage,
        show(out_dir)))
    t_render = time.perf_counter()
    sys.excepthook = excepthook
    try:
        result = bpy.ops.render.render(animation=True, scene=scene.name)
    except RuntimeError as ex:
        die("render failed: {}".format(ex), 1)
    finally:
        sys.excepthook = default_excepthook
    if result != {'FINISHED'}:
        die("render did not finish: {}".format(result), 1)

    missing = [path for frame in frames for path in written.get(frame, [
        os.path.join(out_dir, "frame_{:04d}.exr".format(frame)),
        os.path.join(out_dir, "frame_{:04d}.png".format(frame))]) if not os.path.isfile(path)]
    missing += ["frame {} (never written)".format(f) for f in frames if f not in written]
    if missing:
        die("missing output: " + ", ".join(missing), 1)

    elapsed = time.perf_counter() - t_render
    log("done: {} frame{} in {:.2f} s ({:.2f} s per frame; {:.2f} s including start-up)".format(
        len(frames), "" if len(frames) == 1 else "s", elapsed,
        elapsed / max(1, len(frames)), time.perf_counter() - t_start))
    return 0


if __name__ == "__main__":
    sys.exit(main())
