"""Helpers for tests that drive Blender: scenes from the example blends, renders
with either engine read back as linear float images."""

import os
import tempfile
from pathlib import Path

import numpy as np

from restir_gi.core.camera.film import read_exr

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "example_blends"


def open_example(name):
    import bpy
    bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / name))
    return bpy.context.scene


def set_resolution(scene, width, height):
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100


def setup_cycles(scene, samples, seed, bounces):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.seed = seed
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    # Filter Glossy (default 1) roughens glossy and glass lobes after a
    # diffuse bounce, a biased blur of caustics; the comparisons are with
    # Cycles' unblurred light transport.
    c.blur_glossy = 0.0
    # Classic sampling (Tabulated Sobol: an independent sequence per pixel
    # and seed). The factory scene of Blender 5.2 samples with Automatic, a
    # blue-noise pattern that shares one sequence among the image's pixels;
    # its renders with seeds 1 and 2 differ half as much as independent
    # renders do, which halves the noise estimate of compare_with_cycles and
    # doubles its chi. 5.0's factory scene used Classic. Expectations are the
    # same either way: the pattern only changes noise.
    c.sampling_pattern = "TABULATED_SOBOL"
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2


def setup_restir(scene, samples, seed, bounces, mode="PATH"):
    scene.render.engine = "RESTIR_GI"
    s = scene.restir_gi
    s.mode = mode
    s.samples = samples
    s.seed = seed
    s.max_bounces = s.diffuse_bounces = s.glossy_bounces = s.transmission_bounces = bounces


def render_image(scene, view=None):
    """Render the current frame and return (H, W, 3) linear float32, row 0 at
    the bottom. view: the suffix of one view's file with stereoscopy ("R")."""
    import bpy
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    with tempfile.TemporaryDirectory() as tmp:
        scene.render.filepath = os.path.join(tmp, "render.exr")
        bpy.ops.render.render(write_still=True)
        return read_exr(os.path.join(tmp, "render.exr" if view is None else f"render_{view}.exr"))


def block_means(img, block):
    h, w = img.shape[:2]
    lum = img[..., :3] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    return lum[: h - h % block, : w - w % block].reshape(h // block, block, w // block, block).mean(axis=(1, 3))


def diffuse_material(name, color):
    """A material whose surface is a single Diffuse BSDF of the given colour."""
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new("ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (*color, 1.0)
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return mat


def compare_with_cycles(scene, samples, bounces, block=8, clamp=None, view=None):
    """Render with both engines twice (seeds 1 and 2) and compare.

    clamp: compare min(pixel, clamp) instead of the pixels (both engines
    alike), so directly visible emitters, whose edges hold most of the
    anti-aliasing noise, do not drown what the comparison is about.
    view: compare that view's image (render_image) of a stereo render.

    Returns a dict: ours and cycles (mean images), ratio of mean luminances,
    and chi: the squared block differences over their variance, estimated per
    engine from its two independent renders as ((a - b) / 2)^2. Near 1 when the
    engines agree up to noise; a brightness convention off by a few percent or a
    missing light path pushes it far above.
    """
    renders = {}
    for name, setup in (("ours", setup_restir), ("cycles", setup_cycles)):
        renders[name] = []
        for seed in (1, 2):
            setup(scene, samples, seed, bounces)
            img = render_image(scene, view)
            renders[name].append(img if clamp is None else np.minimum(img, clamp))
    o = [block_means(i, block) for i in renders["ours"]]
    c = [block_means(i, block) for i in renders["cycles"]]
    o_mean, c_mean = (o[0] + o[1]) / 2, (c[0] + c[1]) / 2
    var = ((o[0] - o[1]) / 2) ** 2 + ((c[0] - c[1]) / 2) ** 2
    return {"ours": (renders["ours"][0] + renders["ours"][1]) / 2,
            "cycles": (renders["cycles"][0] + renders["cycles"][1]) / 2,
            "ours_mean": float(o_mean.mean()), "cycles_mean": float(c_mean.mean()),
            "ratio": float(o_mean.mean() / c_mean.mean()),
            "chi": float(((o_mean - c_mean) ** 2).sum() / var.sum())}


class Recorder:
    """What a depsgraph_update_post handler sees, as the tuples sync takes."""

    def __init__(self):
        self.items = []

    def __call__(self, _scene, depsgraph):
        for u in depsgraph.updates:
            self.items.append((u.id.original, u.is_updated_transform, u.is_updated_geometry,
                               u.is_updated_shading))

    def edit(self, change):
        """Apply change(), let the depsgraph evaluate, return the updates seen."""
        import bpy
        handlers = bpy.app.handlers.depsgraph_update_post
        if self not in handlers:        # loading a file drops the handlers
            handlers.append(self)
        self.items = []
        change()
        bpy.context.view_layer.update()
        return self.take()

    def take(self):
        """The updates seen since the last call."""
        items, self.items = self.items, []
        return items


def block_error_after_change(scene, change, samples, bounces, block=8):
    """Mean absolute block difference between Cycles' render of ``scene``
    and ours after ``change()``: what a can-fail test asserts is large.
    ``change`` may return a second change: then (error before it, after)."""
    setup_cycles(scene, samples, 1, bounces)
    cycles = block_means(render_image(scene), block)
    setup_restir(scene, samples, 1, bounces)
    more = change()
    ours = block_means(render_image(scene), block)
    if more is None:
        return float(np.abs(ours - cycles).mean())
    more()
    moved = block_means(render_image(scene), block)
    return float(np.abs(ours - cycles).mean()), float(np.abs(moved - cycles).mean())


def pixel_difference(scene, samples, bounces=1):
    """(mean |ours - Cycles|, the noise of the two engines' seeds) of pixel
    by pixel renders, each engine's two seeds averaged: what the
    pixel-by-pixel tests compare."""
    images = {}
    for name, setup, seed in (("ours", setup_restir, 1), ("ours2", setup_restir, 2),
                              ("cycles", setup_cycles, 1), ("cycles2", setup_cycles, 2)):
        setup(scene, samples, seed, bounces)
        images[name] = render_image(scene)
    assert images["cycles"].std() > 0.05                        # a pattern, not a flat colour
    diff = np.abs((images["ours"] + images["ours2"]) - (images["cycles"] + images["cycles2"])) / 2
    noise = np.hypot(images["ours"] - images["ours2"], images["cycles"] - images["cycles2"]) / 2
    return float(diff.mean()), float(noise.mean())
