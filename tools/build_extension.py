#!/usr/bin/env python3
"""Build the Blender extension package ``dist/<id>-<version>.zip``.

Steps:
1. Download every wheel listed in ``blender_manifest.toml`` into ``wheels/``
   (files already present with the expected SHA-256 are kept) with
   ``python -m pip download --no-deps --only-binary=:all: ...``.
2. Run Blender's own extension builder, ``blender_ext.py``, which ships inside
   the ``bpy`` wheel (``bpy/<version>/scripts/addons_core/bl_pkg/cli/``):
   ``build`` the package, then ``validate`` the resulting zip.
3. Print the path of the zip (last line of stdout).

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
    "embreex-4.4.0.post1-cp311-cp311-macosx_13_0_arm64.whl":
        "3ed370224566681071f245bbc5104feebee1354097679ab69cb3a70c94633cb3",
    "embreex-4.4.0.post1-cp311-cp311-macosx_13_0_x86_64.whl":
        "85d9b232805e95be845ee5d77ddea4e6b21c992b7e60fa7bdf4f578b84797a15",
    "embreex-4.4.0.post1-cp311-cp311-win_amd64.whl":
        "3df27becf6a12b59f5a469bc5271622e26387d52a15880edd29aa564246e7176",
    "openexr-3.5.3-cp311-cp311-manylinux_2_28_x86_64.whl":
        "45a35cb35b38b83635dc149d82627a618f8537f339753dc045f409b6dec0ac4c",
    "openexr-3.5.3-cp311-cp311-macosx_11_0_arm64.whl":
        "1d50c03e12baa9a469f71e33aab890c5cc897a0d4abe3eae90b32b8555ce4cd2",
    "openexr-3.5.3-cp311-cp311-macosx_10_15_x86_64.whl":
        "649385e6ffa310098c0d6df44f6b3afe6d38e43c3d91f89f898b73a0b36eb4d2",
    "openexr-3.5.3-cp311-cp311-win_amd64.whl":
        "6dd26f84df0cbd1468937bbbff8f06e598dcdc19f011139b775dab37898b9deb",
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output-dir", default=os.path.join(REPO_ROOT, "dist"),
                        help="directory of the built zip (default: <repo>/dist)")
    parser.add_argument("--skip-download", action="store_true",
                        help="do not download wheels (they must already be in wheels/)")
    args = parser.parse_args(argv)

    manifest = read_manifest()
    wheels = manifest.get("wheels", [])
    for wheel in wheels:
        if args.skip_download:
            if not os.path.isfile(os.path.join(REPO_ROOT, wheel)):
                fail("missing " + wheel)
        else:
            download_wheel(wheel)

    output_dir = os.path.abspath(args.output_dir)
    os.makedirs(output_dir, exist_ok=True)
    zip_path = os.path.join(output_dir, "{}-{}.zip".format(manifest["id"], manifest["version"]))

    blender_ext = find_blender_ext()
    log("builder: " + blender_ext)
    if os.path.exists(zip_path):
        os.remove(zip_path)
    run_blender_ext(blender_ext, ["build", "--source-dir", REPO_ROOT, "--output-dir", output_dir])
    if not os.path.isfile(zip_path):
        fail("the builder did not write " + zip_path)
    run_blender_ext(blender_ext, ["validate", zip_path])

    size_mb = os.path.getsize(zip_path) / 1e6
    log("built {} ({:.1f} MB)".format(zip_path, size_mb))
    print(zip_path, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
