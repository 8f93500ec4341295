"""core.scene_patch: a twin's copy of last frame's context, brought to the
parent's by a ScenePatch after an object moved (arrays edited in place and
the DynamicAccel updated, as the add-on does between frames), answers rays
and renders as the parent's does, frame after frame; what cannot be sent is
refused, and a copy that ends up different says so."""

import copy

import numpy as np
import pytest

from restir_gi.core import scene_patch
from restir_gi.core.integrators import transparency
from restir_gi.core.geometry.dynamic_accel import DynamicAccel
from restir_gi.core.integrators.base import RAY_EPS_RELATIVE, RenderContext
from restir_gi.core.lights.light_set import LightSet
from restir_gi.core.render import RenderSettings, render_frame
from support.scenes import cornell_box

# Triangles of cornell_box: five walls (10), the tall box (12), the short box
# (12), the emitter (2); vertices: 20, 24, 24, 4.
OBJECT_IDS = np.repeat(np.arange(4), [10, 12, 12, 2]).astype(np.int32)
SHORT_BOX_VERTICES = slice(44, 68)


def context(scene, accel):
    return RenderContext(scene, transparency.wrap(accel, scene), LightSet(scene),
                         RAY_EPS_RELATIVE * scene.extent())


def first_frame():
    """(the parent's context, the twin's: independent equal copies, as a fork gives)."""
    scene = cornell_box("emitter", 24, 24)
    scene.object_ids = OBJECT_IDS.copy()
    scene.object_keys = ["walls", "tall", "short", "lamp"]
    scene.versions = (0, 0)
    twin_scene = copy.deepcopy(scene)
    make = lambda s: context(s, DynamicAccel(s.vertices, s.triangles, s.object_ids, s.object_keys))  # noqa: E731
    return make(scene), make(twin_scene)


def move_short_box(ctx, dx):
    """The parent's next frame: the box moved in place, the structure
    updated, a new Scene and LightSet (the add-on's _build_context)."""
    acc = scene_patch.bare(ctx.accel)
    scene = copy.copy(ctx.scene)
    scene.vertices[SHORT_BOX_VERTICES, 0] += dx
    acc.update(scene.vertices, scene.triangles, scene.object_ids, scene.object_keys, changed={"short"})
    scene.versions = (ctx.scene.versions[0] + 1, ctx.scene.versions[1] + 1)
    return context(scene, acc)


def rays(rng, n=3000):
    o = np.float32([0, -3.9, 1]) + rng.normal(scale=0.05, size=(n, 3)).astype(np.float32)
    d = rng.uniform(-1, 1, (n, 3)).astype(np.float32) + np.float32([0, 2.0, 0])
    return o, (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)


def test01_patched_twin_matches_the_parent_frame_after_frame(rng):
    parent, twin = first_frame()
    o, d = rays(rng)
    for dx in (0.1, 0.15, -0.05):        # the first move, then moves of a dynamic object
        before = scene_patch.accel_updates(parent)
        new = move_short_box(parent, dx)
        patch = scene_patch.make(parent, new, before)
        assert patch is not None and patch.update[0] == "update" and patch.new_lights
        twin = scene_patch.apply(twin, patch)
        a, b = new.accel.intersect_closest(o, d), twin.accel.intersect_closest(o, d)
        assert a.hit.mean() > 0.5
        for name in ("hit", "prim", "t", "u", "v"):
            np.testing.assert_array_equal(getattr(b, name), getattr(a, name))
        np.testing.assert_array_equal(twin.scene.vertices, new.scene.vertices)
        settings = RenderSettings(samples=1, max_bounces=3, seed=dx > 0)
        np.testing.assert_array_equal(render_frame(twin, settings).mean(), render_frame(new, settings).mean())
        parent = new
    assert scene_patch.bare(twin.accel).dynamic_keys == {"short"}


def test02_what_cannot_be_sent_forks_anew(monkeypatch):
    parent, _ = first_frame()
    before = scene_patch.accel_updates(parent)
    new = move_short_box(parent, 0.1)
    assert scene_patch.make(parent, new, before) is not None
    assert scene_patch.make(parent, move_short_box(new, 0.1), before) is None    # two edits since
    assert scene_patch.make(parent, new, None) is None
    new.scene.compiled = lambda: None                   # an attribute that cannot be pickled
    assert scene_patch.make(parent, new, before) is None
    del new.scene.compiled
    monkeypatch.setattr(scene_patch, "MAX_BYTES", 1000)
    assert scene_patch.make(parent, new, before) is None


def test03_a_copy_that_differs_raises():
    parent, twin = first_frame()
    before = scene_patch.accel_updates(parent)
    patch = scene_patch.make(parent, move_short_box(parent, 0.1), before)
    patch.fingerprint = patch.fingerprint[:-1] + (patch.fingerprint[-1] * 2,)
    with pytest.raises(RuntimeError, match="differs"):
        scene_patch.apply(twin, patch)
