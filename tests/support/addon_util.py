"""Helpers of the add-on tests that render through Blender's own operator:
scenes built by script, EXR reading, and the ``reports`` fixture (conftest.py).

Reports are captured by wrapping the engine handed to the final render with a
proxy that records every ``report`` call (RenderEngine methods are resolved by
Blender before Python attributes, so patching the class would not see them);
the same proxy stands in for ``test_break`` in the cancel test.
"""

import os

import numpy as np

from support.blender_util import diffuse_material

MODES = ["PATH", "RESTIR_BIASED", "RESTIR_UNBIASED"]


def fresh(width=32, height=32, samples=4, mode="PATH"):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "RESTIR_GI"
    scene.restir_gi.mode = mode
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.restir_gi.samples = samples
    scene.restir_gi.max_bounces = 2
    scene.restir_gi.seed = 0
    return scene


def add_mesh(name, verts, faces, location=(0, 0, 0), mat=None):
    import bpy
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(verts, np.float64).reshape(-1, 3).tolist(), [],
                   [[int(i) for i in f] for f in faces])
    me.update()
    ob = bpy.data.objects.new(name, me)
    ob.location = location
    bpy.context.scene.collection.objects.link(ob)
    if mat is not None:
        me.materials.append(mat)
    return ob


def rect(x0, x1, y0, y1, z=0.0):
    return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float), [[0, 1, 2, 3]]


def emission(name, strength):
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeEmission")
    node.inputs["Strength"].default_value = strength
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return mat


def world(color, strength=1.0):
    import bpy
    w = bpy.data.worlds.new("World")
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    bpy.context.scene.world = w
    return w


def camera(location=(0, 0, 5), rotation=(0, 0, 0), **props):
    import bpy
    data = bpy.data.cameras.new("Camera")
    for key, value in props.items():
        setattr(data, key, value)
    ob = bpy.data.objects.new("Camera", data)
    ob.location, ob.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.scene.camera = ob
    return ob


def render_exr(scene, path, multilayer=False):
    """Render the current frame to `path` (32-bit EXR)."""
    import bpy
    settings = scene.render.image_settings
    if multilayer:
        settings.media_type = "MULTI_LAYER_IMAGE"
    else:
        settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    assert os.path.isfile(path)


def read_passes(path):
    """{pass name: (H, W, C) float32, row 0 at the bottom} of a multilayer EXR."""
    import OpenEXR
    out = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            groups = {}
            for name, ch in part.channels.items():
                layer_pass, chan = name.rsplit(".", 1)
                groups.setdefault(layer_pass.split(".", 1)[-1], {})[chan] = ch.pixels
            for pass_name, chans in groups.items():
                order = [c for c in "RGBAXYZ" if c in chans]
                out[pass_name] = np.stack([chans[c] for c in order], axis=2)[::-1].astype(np.float32)
    return out


class EngineProxy:
    """Stands in for the RenderEngine inside the final render: records reports,
    optionally answers test_break and watches progress and the end of the
    result; forwards everything else."""

    def __init__(self, engine, log, test_break=None, on_progress=None, on_end=None):
        self._engine, self._log = engine, log
        self._test_break, self._on_progress, self._on_end = test_break, on_progress, on_end

    def report(self, kind, message):
        self._log.append((next(iter(kind)), message))
        self._engine.report(kind, message)

    def test_break(self):
        return self._test_break() if self._test_break else self._engine.test_break()

    def update_progress(self, value):
        if self._on_progress:
            self._on_progress(value)
        self._engine.update_progress(value)

    def end_result(self, result, *args, **kwargs):
        if self._on_end:
            self._on_end()
        return self._engine.end_result(result, *args, **kwargs)

    def __getattr__(self, name):
        return getattr(self._engine, name)


def capture_reports(addon, monkeypatch):
    """Every report the engine makes, as (type, message) in `.log` (the
    ``reports`` fixture of conftest.py)."""
    final = addon.restir_addon.final
    log = []
    real = final.render
    options = {}

    def wrapped(engine, depsgraph):
        return real(EngineProxy(engine, log, **options), depsgraph)

    monkeypatch.setattr(final, "render", wrapped)
    return Reports(log, options)


class Reports:
    """The recorded reports; `options` are handed to the next EngineProxy."""

    def __init__(self, log, options):
        self.log, self.options = log, options

    def of(self, kind):
        return [m for k, m in self.log if k == kind]


def lit_plane_scene(width=32, height=32, samples=4, mode="PATH"):
    """A diffuse plane filling the view of a camera looking straight down, under a grey world."""
    scene = fresh(width, height, samples, mode)
    camera()
    world((0.5, 0.5, 0.5))
    add_mesh("Plane", *rect(-5, 5, -5, 5), mat=diffuse_material("Orange", (0.6, 0.3, 0.1)))
    return scene


def assert_valid(img, shape):
    assert img.shape[:2] == shape
    assert np.isfinite(img).all()


class FakePass:
    def __init__(self, store, name):
        self.rect = self
        self._store, self.name = store, name

    def foreach_set(self, data):
        self._store[self.name] = np.array(data, np.float32)


class FakeEngine:
    """The handful of RenderEngine calls the final render makes, recorded."""
    is_animation = False
    is_preview = False

    def __init__(self, names):
        self.pixels, self.log, self.ended = {}, [], False
        passes = {n: FakePass(self.pixels, n) for n in names}
        self.result = type("Result", (), {"layers": [type("Layer", (), {"passes": passes})()]})()

    def begin_result(self, x, y, w, h, layer=None, view=""):
        self.size = (w, h)
        return self.result

    def end_result(self, result):
        self.ended = True

    def report(self, kind, message):
        self.log.append((next(iter(kind)), message))

    def update_stats(self, *args):
        pass

    def update_progress(self, *args):
        pass

    def update_result(self, *args):
        pass

    def test_break(self):
        return False
