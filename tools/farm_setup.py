"""The farm's configuration checks (tools/farm.py): the .blend, the extension
package (built for this platform and the workers' Python), the workers'
Python (with bpy) and repository, the output folder. Standard library only:
on a cluster every worker runs setup_problems itself.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tomllib
import zipfile


def this_platform() -> str:
    """This machine as a Blender platform name: linux-x64, macos-arm64, windows-x64, ..."""
    system = {"linux": "linux", "darwin": "macos", "win32": "windows"}.get(sys.platform, sys.platform)
    machine = platform.machine().lower()
    return "{}-{}".format(system, {"x86_64": "x64", "amd64": "x64", "aarch64": "arm64"}.get(machine, machine))


def default_package(repo: str) -> str | None:
    """render.py's default package in a repository: dist/<id>-<version>.zip."""
    try:
        with open(os.path.join(repo, "blender_manifest.toml"), "rb") as fh:
            manifest = tomllib.load(fh)
        return os.path.join(repo, "dist", "{}-{}.zip".format(manifest["id"], manifest["version"]))
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return None


def package_problem(package: str, python_version: str | None) -> str | None:
    """What keeps Blender here (this platform, Python python_version) from
    installing the package, or None."""
    try:
        with zipfile.ZipFile(package) as zf:
            manifest = tomllib.loads(zf.read("blender_manifest.toml").decode("utf-8"))
    except (OSError, KeyError, zipfile.BadZipFile, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        return (f"{package} is not an extension package ({type(exc).__name__}: {exc}): "
                f"rebuild it with `make build`")
    generated = manifest.get("build", {}).get("generated", {})
    platforms = generated.get("platforms", manifest.get("platforms"))
    here = this_platform()
    if platforms and here not in platforms:
        return (f"{package} is the package for {', '.join(platforms)}, not for this machine ({here}): "
                f"give the {here.replace('-', '_')} package, or build this machine's with `make build`")
    wheels = generated.get("wheels", manifest.get("wheels")) or []
    tags = {os.path.basename(w).split("-")[-3] for w in wheels if w.endswith(".whl")}
    if python_version and tags:
        want = "cp" + python_version.replace(".", "")
        if want not in tags:
            have = ", ".join(f"{t[2]}.{t[3:]}" for t in sorted(tags) if t.startswith("cp"))
            return (f"{package} has no wheels for Python {python_version} (only {have}): "
                    f"rebuild it with `make build` from this version of the repository")
    return None


def writable_problem(path: str, what: str) -> str | None:
    """Whether path can be made and written into (nothing is created here)."""
    if os.path.exists(path) and not os.path.isdir(path):
        return f"{what} {path} is a file, not a folder: give a folder"
    probe = path
    while not os.path.exists(probe):
        parent = os.path.dirname(probe)
        if parent == probe:
            break
        probe = parent
    if not os.access(probe, os.W_OK | os.X_OK):
        return f"{what} {path} cannot be written ({probe} is not writable): give a writable folder"
    return None


def setup_problems(blend: str, out: str, repo: str, python: str, package: str | None,
                   user_resources: str | None) -> list[str]:
    """Configuration errors of the machine this runs on, each with what to do:
    what every chunk's render would fail on. Standard library only (it runs on
    the workers of a cluster too)."""
    problems = []
    if not os.path.isfile(blend):
        problems.append(f"blend file not found: {blend} (it must be at the same path on every worker)")
    if not os.path.isfile(os.path.join(repo, "tools", "render.py")):
        problems.append(f"tools/render.py not found in {repo}: give this repository's path on the "
                        f"workers with --worker-repo")
    python_version = None
    try:
        proc = subprocess.run([python, "-c", "import importlib.util, sys; print('%d.%d' % "
                               "sys.version_info[:2], importlib.util.find_spec('bpy') is not None)"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=120)
        output = proc.stdout.split()
        if proc.returncode != 0 or len(output) != 2:
            problems.append(f"the workers' Python {python} does not run (exit status {proc.returncode}): "
                            f"give one with --worker-python")
        elif output[1] != "True":
            problems.append(f"the workers' Python {python} has no bpy module: give the Python of the "
                            f"environment `make venv` makes (.venv/bin/python; .venv-py311/bin/python "
                            f"with LINE=py311) with --worker-python")
        else:
            python_version = output[0]
    except (OSError, subprocess.TimeoutExpired) as exc:
        problems.append(f"the workers' Python {python} cannot be started ({exc}): give one with "
                        f"--worker-python")
    if package is None:
        package = default_package(repo)
    if package is None:
        problems.append(f"no blender_manifest.toml in {repo}: give the repository with --worker-repo "
                        f"or the package with --package ZIP")
    elif not os.path.isfile(package):
        problems.append(f"extension package not found: {package}: build it with `make build`, or "
                        f"give one with --package ZIP")
    elif (problem := package_problem(package, python_version)) is not None:
        problems.append(problem)
    for path, what in ((out, "output folder"), (user_resources, "Blender user folder")):
        if path is not None and (problem := writable_problem(path, what)) is not None:
            problems.append(problem)
    return problems
