"""The import graph of core/ and restir_addon/: no circles, and every import
points down the order of LAYERS (a package may import its own modules and
anything in a lower layer). Deferred imports count as imports: an import
inside a function is no way around the order."""

import ast
from pathlib import Path

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "blender_manifest.toml").exists())

# Lowest first. A module belongs to the longest name here that prefixes it.
LAYERS = [
    ["core.util", "core.scene"],
    ["core.workers"],
    ["core.sampling"],
    ["core.geometry", "core.camera"],
    ["core.bsdfs"],
    ["core.materials"],
    ["core.lights"],
    ["core.integrators"],
    ["core.restir"],
    ["core.scene_patch", "core.object_motion"],
    ["core.render"],
    ["core"],
    ["restir_addon.defaults"],
    ["restir_addon.memory", "restir_addon.passes", "restir_addon.properties", "restir_addon.ui"],
    ["restir_addon.export"],
    ["restir_addon.sync"],
    ["restir_addon.motion_blur"],
    ["restir_addon.render_camera"],
    ["restir_addon.state"],
    ["restir_addon.final"],
    ["restir_addon.viewport"],
    ["restir_addon.engine"],
    ["restir_addon"],
]


def module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph():
    """{module: {imported module}} over core/ and restir_addon/ (the package's own modules only)."""
    files = {module_name(p): p for top in ("core", "restir_addon") for p in (ROOT / top).rglob("*.py")}
    edges = {m: set() for m in files}
    for mod, path in files.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    parts = package.split(".")
                    base = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                names = [f"{base}.{a.name}" if base else a.name for a in node.names]
                targets = [n if n in files else base for n in names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            edges[mod].update(t for t in targets if t in files and t != mod)
    return edges


def layer_of(mod):
    best = None
    for i, names in enumerate(LAYERS):
        for name in names:
            if (mod == name or mod.startswith(name + ".")) and (best is None or len(name) > len(best[1])):
                best = (i, name)
    return best


def upward_imports(edges):
    """'a -> b' for each import of a module b not below a's layer (or a
    sibling package's in the same layer)."""
    upward = []
    for mod, targets in edges.items():
        i, own = layer_of(mod)
        for t in targets:
            j, other = layer_of(t)
            if j > i or (j == i and other != own):
                upward.append(f"{mod} -> {t}")
    return sorted(upward)


def circles(edges):
    """Each import circle found by a depth-first walk, as the modules along it."""
    seen, on_path, found = set(), [], []

    def visit(m):
        if m in on_path:
            found.append(on_path[on_path.index(m):] + [m])
            return
        if m in seen:
            return
        seen.add(m)
        on_path.append(m)
        for t in sorted(edges.get(m, ())):
            visit(t)
        on_path.pop()

    for m in sorted(edges):
        visit(m)
    return found


def test01_every_module_has_a_layer():
    assert [m for m in import_graph() if layer_of(m) is None] == []


def test02_imports_point_down():
    assert upward_imports(import_graph()) == []


def test03_no_circles():
    assert circles(import_graph()) == []


def test04_the_checks_catch_what_they_look_for():
    assert upward_imports({"core.util.rows": {"core.restir.reservoirs"}, "core.restir.reservoirs": set()}) \
        == ["core.util.rows -> core.restir.reservoirs"]
    assert upward_imports({"core.lights.analytic": {"core.camera.film"}, "core.camera.film": set()}) == []
    assert upward_imports({"core.geometry.accel": {"core.camera.film"}, "core.camera.film": set()}) \
        == ["core.geometry.accel -> core.camera.film"]
    assert circles({"core.restir.a": {"core.restir.b"}, "core.restir.b": {"core.restir.a"}}) \
        == [["core.restir.a", "core.restir.b", "core.restir.a"]]


def test05_core_never_imports_bpy():
    offenders = []
    for path in (ROOT / "core").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            if any(n == "bpy" or n.startswith("bpy.") or n in ("mathutils", "gpu") for n in names):
                offenders.append(str(path.relative_to(ROOT)))
    assert offenders == []
