#!/usr/bin/env python3
"""Build the Blender extension packages, one per platform, into ``dist/``.

Steps:
1. Download every wheel listed in ``blender_manifest.toml`` into ``wheels/``
   (files already present with the expected SHA-256 are kept) with
   ``python -m pip download --no-deps --only-binary=:all: ...``, and check
   each against the SHA-256 published on PyPI (``WHEEL_SHA256`` below).
2. Run Blender's own extension builder, ``blender_ext.py``, which ships inside
   the ``bpy`` wheel (``bpy/<version>/scripts/addons_core/bl_pkg/cli/``):
   ``build --split-platforms`` writes ``<id>-<version>-<platform>.zip`` for
   each platform of the manifest (``linux_x64``, ``macos_arm64``,
   ``macos_x64``, ``windows_x64``), each holding only its own platform's
   wheels (for every Python of the manifest); then ``validate`` each zip.
3. Copy the package of this machine's platform to ``<id>-<version>.zip``, the
   package that ``tools/render.py``, ``tools/farm.py`` and the tests install,
   and print its path (last line of stdout). On a machine of no platform of
   the manifest the packages are built all the same, but the command fails
   (the renderer cannot run there).

Usage: python tools/build_extension.py [--output-dir DIR] [--skip-download]

Only the standard library is needed, plus an installed ``bpy`` module (it is
located with importlib, not imported) and ``pip``.
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import importlib.util
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import tomllib

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MANIFEST = os.path.join(REPO_ROOT, "blender_manifest.toml")

# SHA-256 of the bundled wheels, as published on PyPI. A wheel added to the
# manifest must be added here too (the error message prints its hash).
WHEEL_SHA256 = {
    "embreex-4.4.0.post1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl":
        "2cd0f7d5c6342e6247e31f700761689cae7829454d8c6de0c41e62124a023e1f",
    "embreex-4.4.0.post1-cp313-cp313-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl":
        "83165d2bb0436ab9b07d8e7236a0f2509c7868b3a85f2fbd8c41b4d023e88e38",
    "embreex-4.4.0.post1-cp314-cp314-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl":
        "cb799b02e9b140b6e64a6e5a4caf476494ea12c67828d92709effcec990fc47f",
    "openexr-3.5.3-cp311-cp311-manylinux_2_28_x86_64.whl":
        "45a35cb35b38b83635dc149d82627a618f8537f339753dc045f409b6dec0ac4c",
    "openexr-3.5.3-cp313-cp313-manylinux_2_28_x86_64.whl":
        "0f1c9790e2b57dbbcde9f74d1788e18cb627333066101d63bbfc6be091ff24fa",
    "openexr-3.5.3-cp314-cp314-manylinux_2_28_x86_64.whl":
        "dd27c20ccfdcd1d8eade0c35f1c5d4502e2a81fcf78c52130aa55619abd11aa5",
    "embreex-4.4.0.post1-cp311-cp311-macosx_13_0_arm64.whl":
        "3ed370224566681071f245bbc5104feebee1354097679ab69cb3a70c94633cb3",
    "embreex-4.4.0.post1-cp313-cp313-macosx_13_0_arm64.whl":
        "8e0ec6325caab812cb428da4cecb8905b40c6d5bda386ffb73d44bbf2aa7af56",
    "embreex-4.4.0.post1-cp314-cp314-macosx_13_0_arm64.whl":
        "d1d9193b99fb4b704b5982970dd79cd68a12603ac6d72d6ea59c701bd705b8e3",
    "openexr-3.5.3-cp311-cp311-macosx_11_0_arm64.whl":
        "1d50c03e12baa9a469f71e33aab890c5cc897a0d4abe3eae90b32b8555ce4cd2",
    "openexr-3.5.3-cp313-cp313-macosx_11_0_arm64.whl":
        "2dde224419817fc7b8ca58fbff8b89cadb63ef0782b59a828730e8fa64d08d6a",
    "openexr-3.5.3-cp314-cp314-macosx_11_0_arm64.whl":
        "0b343675f7463d88ef6366d696fd5568e6fd93969f49181cbfd03dacebb1b9d6",
    "embreex-4.4.0.post1-cp311-cp311-macosx_13_0_x86_64.whl":
        "85d9b232805e95be845ee5d77ddea4e6b21c992b7e60fa7bdf4f578b84797a15",
    "embreex-4.4.0.post1-cp313-cp313-macosx_13_0_x86_64.whl":
        "b8bd326b36151373adaad23268b60b39d20ec8a371eb1bae309a31e4ab78ac71",
    "embreex-4.4.0.post1-cp314-cp314-macosx_13_0_x86_64.whl":
        "78408e6bebf154294acee729bd1e0ea0d8d843f37f190f8c4ed058347d9eff3a",
    "openexr-3.5.3-cp311-cp311-macosx_10_15_x86_64.whl":
        "649385e6ffa310098c0d6df44f6b3afe6d38e43c3d91f89f898b73a0b36eb4d2",
    "openexr-3.5.3-cp313-cp313-macosx_10_15_x86_64.whl":
        "ce52f9ab9f0a9503cc329ecfc2d1e348e393d9410d07145229b5514f6b06a621",
    "openexr-3.5.3-cp314-cp314-macosx_10_15_x86_64.whl":
        "d1de85f698782c4d18cd04fda06e5ce02aa9e3505c972881a70f74612e540f4b",
    "embreex-4.4.0.post1-cp311-cp311-win_amd64.whl":
        "3df27becf6a12b59f5a469bc5271622e26387d52a15880edd29aa564246e7176",
    "embreex-4.4.0.post1-cp313-cp313-win_amd64.whl":
        "506009885b72923661f2b5cd3decd593b9340e3ef06ddb70763303fc5982253e",
    "embreex-4.4.0.post1-cp314-cp314-win_amd64.whl":
        "9b8d24212eff720f4308d3861621d8cdfbf5d7259fa2412269d35f30d989f50c",
    "openexr-3.5.3-cp311-cp311-win_amd64.whl":
        "6dd26f84df0cbd1468937bbbff8f06e598dcdc19f011139b775dab37898b9deb",
    "openexr-3.5.3-cp313-cp313-win_amd64.whl":
        "885609f0329669336b24a22d9124d3cd3659dfdcafdc36d79a5ed8239c5f447c",
    "openexr-3.5.3-cp314-cp314-win_amd64.whl":
        "6726dd95b36c8e99cf02d025b5cfa294877acd9f2b9c4120971d3b15ff0c0884",
}


def log(msg: str) -> None:
    print("[build_extension] " + msg, flush=True)


def fail(msg: str) -> None:
    print("[build_extension] error: " + msg, file=sys.stderr, flush=True)
    sys.exit(1)


def sha256_of(path: str) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def read_manifest() -> dict:
    if not os.path.isfile(MANIFEST):
        fail("missing " + MANIFEST)
    with open(MANIFEST, "rb") as fh:
        return tomllib.load(fh)


def parse_wheel_filename(filename: str) -> tuple[str, str, str, str, list[str]]:
    """Split ``name-version[-build]-python-abi-platform.whl`` into its tags."""
    parts = filename[:-len(".whl")].split("-")
    if len(parts) not in (5, 6):
        fail("not a wheel file name: " + filename)
    name, version = parts[0], parts[1]
    python_tag, abi_tag, platform_tag = parts[-3:]
    return name, version, python_tag, abi_tag, platform_tag.split(".")


def download_wheel(wheel_rel: str) -> None:
    filename = os.path.basename(wheel_rel)
    target = os.path.normpath(os.path.join(REPO_ROOT, wheel_rel))
    expected = WHEEL_SHA256.get(filename)

    if os.path.isfile(target):
        actual = sha256_of(target)
        if expected is None:
            fail("no SHA-256 recorded in WHEEL_SHA256 for {} (its hash: {})".format(filename, actual))
        if actual == expected:
            log("present: " + wheel_rel)
            return
        log("hash mismatch, downloading again: " + wheel_rel)
        os.remove(target)

    name, version, python_tag, abi_tag, platforms = parse_wheel_filename(filename)
    if not (python_tag.startswith("cp") and python_tag[2:].isdigit()):
        fail("expected a CPython wheel (cpXY tag): " + filename)
    python_version = python_tag[2] + "." + python_tag[3:]

    os.makedirs(os.path.dirname(target), exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="wheel-dl-") as tmp:
        cmd = [
            sys.executable, "-m", "pip", "download",
            "--no-deps", "--only-binary=:all:",
            "--python-version", python_version,
            "--implementation", "cp",
            "--abi", abi_tag,
        ]
        for platform in platforms:
            cmd += ["--platform", platform]
        cmd += ["--dest", tmp, "{}=={}".format(name, version)]
        log("downloading: " + filename)
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if proc.returncode != 0:
            sys.stderr.write(proc.stdout)
            fail("pip download failed for " + filename)
        got = os.path.join(tmp, filename)
        if not os.path.isfile(got):
            fail("pip downloaded {} instead of {}".format(sorted(os.listdir(tmp)), filename))
        actual = sha256_of(got)
        if expected is None:
            fail("no SHA-256 recorded in WHEEL_SHA256 for {} (downloaded hash: {})".format(filename, actual))
        if actual != expected:
            fail("SHA-256 mismatch for {}: got {}, expected {}".format(filename, actual, expected))
        shutil.move(got, target)


def find_blender_ext() -> str:
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        fail("the bpy module is not installed in this Python ({}); run `make venv` first".format(sys.executable))
    for location in spec.submodule_search_locations:
        found = sorted(glob.glob(os.path.join(
            location, "*", "scripts", "addons_core", "bl_pkg", "cli", "blender_ext.py")))
        if found:
            return found[-1]
    fail("blender_ext.py not found inside the bpy module")
    return ""  # unreachable


def run_blender_ext(blender_ext: str, args: list[str]) -> None:
    cmd = [sys.executable, blender_ext] + args
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for line in proc.stdout.splitlines():
        log("  " + line)
    if proc.returncode != 0:
        fail("blender_ext.py {} failed (exit code {})".format(args[0], proc.returncode))


def host_platform() -> str:
    """This machine as a Blender platform name: linux-x64, macos-arm64, windows-x64, ..."""
    system = {"linux": "linux", "darwin": "macos", "win32": "windows"}.get(sys.platform, sys.platform)
    machine = platform.machine().lower()
    machine = {"x86_64": "x64", "amd64": "x64", "aarch64": "arm64"}.get(machine, machine)
    return "{}-{}".format(system, machine)


def package_paths(manifest: dict, output_dir: str) -> tuple[str, dict[str, str]]:
    """(the package of this machine, {platform: its package}) in output_dir,
    named as ``blender_ext.py build --split-platforms`` names them."""
    base = "{}-{}".format(manifest["id"], manifest["version"])
    split = {p: os.path.join(output_dir, "{}-{}.zip".format(base, p.replace("-", "_")))
             for p in manifest.get("platforms", [])}
    return os.path.join(output_dir, base + ".zip"), split


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output-dir", default=os.path.join(REPO_ROOT, "dist"),
                        help="directory of the built packages (default: <repo>/dist)")
    parser.add_argument("--skip-download", action="store_true",
                        help="do not download wheels (they must already be in wheels/)")
    args = parser.parse_args(argv)

    manifest = read_manifest()
    if not manifest.get("platforms"):
        fail("blender_manifest.toml lists no platforms: the packages are split by platform")
    wheels = manifest.get("wheels", [])
    for wheel in wheels:
        if args.skip_download:
            if not os.path.isfile(os.path.join(REPO_ROOT, wheel)):
                fail("missing " + wheel)
        else:
            download_wheel(wheel)

    output_dir = os.path.abspath(args.output_dir)
    os.makedirs(output_dir, exist_ok=True)
    host_zip, split = package_paths(manifest, output_dir)

    blender_ext = find_blender_ext()
    log("builder: " + blender_ext)
    for path in [host_zip, *split.values()]:
        if os.path.exists(path):
            os.remove(path)
    run_blender_ext(blender_ext, ["build", "--split-platforms",
                                  "--source-dir", REPO_ROOT, "--output-dir", output_dir])
    for name, path in split.items():
        if not os.path.isfile(path):
            fail("the builder did not write the {} package {}".format(name, path))
        run_blender_ext(blender_ext, ["validate", path])
        log("built {} ({:.1f} MB)".format(path, os.path.getsize(path) / 1e6))

    host = host_platform()
    if host not in split:
        fail("this machine ({}) is none of the extension's platforms ({}): the packages are "
             "built, but there is none to render with here".format(host, ", ".join(split)))
    shutil.copyfile(split[host], host_zip)
    log("package for this machine ({}): {}".format(host, host_zip))
    print(host_zip, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
