#!/usr/bin/env python3
"""Headless render through the installed ReSTIR GI extension.

The bpy-module equivalent of

    blender -b FILE.blend -E RESTIR_GI -a         (whole animation)
    blender -b FILE.blend -E RESTIR_GI -f N       (one frame, --frame N)

Usage:
    python tools/render.py FILE.blend [--frame N | --frames A-B] [--output DIR]
                           [--samples N] [--chunk-warmup N] [--threads N]
                           [--skip-existing] [--package ZIP] [--user-resources DIR]

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
   of the scene's frame range (or only --frame N, or --frames A-B as
   ``blender -f A..B`` does: one animation job over A..B, the scene's own
   frame range unchanged, so a ReSTIR render that starts after the scene's
   first frame runs its chunk warm-up), writing for each frame
   ``DIR/frame_####.exr`` (multilayer OpenEXR, 32-bit float, linear, all
   passes) and ``DIR/frame_####.png`` (8-bit RGBA through the scene's view
   transform, as Blender writes a PNG). DIR defaults to ``<repo>/out/<blend
   name>``. Both files of a frame are written under ``DIR/.partial/`` first
   and renamed into DIR once complete, so a render killed mid-frame leaves no
   truncated frame. With --skip-existing, frames whose two files are already
   in DIR are not rendered again (a rerun resumes).

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

from frame_range import parse_range, runs

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
    parser.add_argument("--frames", default=None, metavar="A-B",
                        help="render frames A to B as one animation job (like blender -f A..B), "
                             "keeping the scene's frame range")
    parser.add_argument("--skip-existing", action="store_true",
                        help="do not render frames whose EXR and PNG are already in the output directory")
    parser.add_argument("--chunk-warmup", type=int, default=None, metavar="N",
                        help="override scene.restir_gi.chunk_warmup_frames (frames rendered, not "
                             "written, before a range that starts after the scene's first frame)")
    parser.add_argument("--threads", type=int, default=None, metavar="N",
                        help="render threads (like blender -t N); default: the file's setting")
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
    if args.chunk_warmup is not None and args.chunk_warmup < 0:
        parser.error("--chunk-warmup must be at least 0")
    if args.threads is not None and args.threads < 1:
        parser.error("--threads must be at least 1")
    if args.frame is not None and args.frames is not None:
        parser.error("give --frame or --frames, not both")
    if args.frame is not None:
        args.range = (args.frame, args.frame)
    elif args.frames is not None:
        args.range = parse_range(args.frames)
        if args.range is None:
            parser.error("--frames wants A-B (or A..B) with A <= B, e.g. 1-24")
    else:
        args.range = None
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


class install_lock:
    """Only one render at a time installs the package into a user folder
    (farm chunks start together); a no-op where fcntl is missing."""

    def __init__(self, user_resources: str):
        self.path = os.path.join(user_resources, ".install.lock")

    def __enter__(self):
        try:
            import fcntl
        except ImportError:
            self.fh = None
            return self
        os.makedirs(os.path.dirname(self.path), exist_ok=True)
        self.fh = open(self.path, "w")
        fcntl.flock(self.fh, fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc):
        if self.fh is not None:
            self.fh.close()     # releases the lock


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
    import bpy

    with install_lock(user_resources):
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
    if args.chunk_warmup is not None:
        scene.restir_gi.chunk_warmup_frames = args.chunk_warmup
    if args.threads is not None:
        render.threads_mode = 'FIXED'
        render.threads = args.threads

    step = max(1, scene.frame_step)
    first, last = args.range if args.range is not None else (scene.frame_start, scene.frame_end)
    frames = list(range(first, last + 1, step))

    def final_paths(frame: int) -> list[str]:
        return [os.path.join(out_dir, "frame_{:04d}.{}".format(frame, ext)) for ext in ("exr", "png")]

    skipped = []
    if args.skip_existing:
        skipped = [f for f in frames if all(os.path.isfile(p) for p in final_paths(f))]
        if skipped:
            log("{} of {} frames already in {}: skipped".format(len(skipped), len(frames), show(out_dir)))
    todo = [f for f in frames if f not in skipped]

    # Frames are written under .partial/ and renamed into out_dir once both
    # files are complete: a render killed mid-frame leaves no truncated frame.
    partial_dir = os.path.join(out_dir, ".partial")
    os.makedirs(partial_dir, exist_ok=True)
    render.filepath = os.path.join(partial_dir, "frame_####")
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
        # Render Result again as a PNG, restore the EXR settings for the next
        # frame, then move both files into place.
        frame = scene.frame_current
        exr_tmp = scene.render.frame_path(frame=frame)
        settings = scene.render.image_settings
        settings.media_type = 'IMAGE'
        settings.file_format = 'PNG'
        settings.color_mode = 'RGBA'
        settings.color_depth = '8'
        try:
            png_tmp = scene.render.frame_path(frame=frame)
            bpy.data.images['Render Result'].save_render(png_tmp, scene=scene)
        finally:
            (settings.media_type, settings.file_format,
             settings.color_depth, settings.color_mode) = exr_settings
        exr_path, png_path = final_paths(frame)
        os.replace(png_tmp, png_path)
        os.replace(exr_tmp, exr_path)
        written[frame] = [exr_path, png_path]
        log("frame {} ({}/{}): {:.2f} s -> {}, {}".format(
            frame, len(written), len(todo), time.perf_counter() - frame_t0[0],
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
        show(blend), len(todo), "" if len(todo) == 1 else "s",
        todo[0] if todo else "-", todo[-1] if todo else "-",
        render.resolution_x, render.resolution_y, render.resolution_percentage,
        show(out_dir)))
    t_render = time.perf_counter()
    sys.excepthook = excepthook
    try:
        # One animation job per run of missing frames, like blender -f A..B:
        # the scene's frame range stays as saved.
        for a, b in runs(todo, step):
            result = bpy.ops.render.render(animation=True, scene=scene.name,
                                           frame_start=a, frame_end=b)
            if result != {'FINISHED'}:
                die("render did not finish: {}".format(result), 1)
    except RuntimeError as ex:
        die("render failed: {}".format(ex), 1)
    finally:
        sys.excepthook = default_excepthook
    try:
        os.rmdir(partial_dir)
    except OSError:
        pass

    missing = [path for frame in frames for path in final_paths(frame) if not os.path.isfile(path)]
    missing += ["frame {} (never written)".format(f) for f in todo if f not in written]
    if missing:
        die("missing output: " + ", ".join(missing), 1)

    elapsed = time.perf_counter() - t_render
    log("done: {} frame{} in {:.2f} s ({:.2f} s per frame; {:.2f} s including start-up)".format(
        len(todo), "" if len(todo) == 1 else "s", elapsed,
        elapsed / max(1, len(todo)), time.perf_counter() - t_start))
    return 0


if __name__ == "__main__":
    sys.exit(main())
