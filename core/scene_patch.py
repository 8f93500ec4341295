"""A parked twin process following the scene's edits between two frames.

A render loop's twin (core/workers/forked.py) is kept between the frames of an
animation (``Workers.twin``). When objects move, the add-on updates the
combined arrays in place and the DynamicAccel (core/geometry/dynamic_accel.py),
builds a new Scene and a new LightSet where emitters moved. The
twin holds copies of the last frame's: rather than forking a new twin, whose
copy-on-write page faults are paid again every frame, the parent sends a
ScenePatch: the new scene's arrays (any may have changed in place) and the
attributes that are new objects, the acceleration structure's one edit to
repeat, and whether the lights are rebuilt. The twin checks a fingerprint of
what it built; a twin that differs exits and the parent goes on alone.
"""

import dataclasses
import pickle
from dataclasses import dataclass

import numpy as np
from .integrators import transparency
from .lights.light_set import LightSet

MAX_BYTES = 32 << 20     # larger patches fork a new twin instead (a copy of 1M triangles' arrays)


@dataclass
class ScenePatch:
    send: dict              # scene attributes to set: every array, and what is a new object
    keep: list              # scene attributes the twin's copy keeps (the same objects here)
    update: tuple           # DynamicAccel.last_update to replay, or None
    new_lights: bool        # a new LightSet of the patched scene
    eps: float
    fingerprint: tuple


def bare(accel):
    """The acceleration structure under a transparency wrapper."""
    return getattr(accel, "inner", accel)


def accel_updates(ctx):
    """Edits of the context's acceleration structure so far (None: it
    cannot repeat them)."""
    return getattr(bare(ctx.accel), "updates", None)


def fingerprint(ctx):
    """What must agree between the parent's context and the twin's patched copy."""
    acc = bare(ctx.accel)
    return (type(ctx.accel).__name__, ctx.scene.triangle_count, acc.triangle_count,
            acc.dynamic_triangle_count, len(acc.dynamic_keys), ctx.lights.count, float(ctx.eps))


def make(old_ctx, new_ctx, old_updates):
    """(parent) The ScenePatch taking the twin's copy of old_ctx, whose
    acceleration structure had had ``old_updates`` edits, to new_ctx; None
    where there is none (another structure, more than one edit since, an
    attribute that cannot be sent, or too much to send)."""
    acc = bare(new_ctx.accel)
    if bare(old_ctx.accel) is not acc or old_updates is None or getattr(acc, "updates", None) is None:
        return None
    edits = acc.updates - old_updates
    if edits not in (0, 1):
        return None
    old, new = vars(old_ctx.scene), vars(new_ctx.scene)
    send, keep = {}, []
    for k, v in new.items():
        if isinstance(v, np.ndarray) or k not in old or old[k] is not v:
            send[k] = v
        else:
            keep.append(k)
    buffers = []
    try:
        head = pickle.dumps(send, protocol=5, buffer_callback=buffers.append)
    except Exception:       # noqa: BLE001 -- compiled shading graphs, say: fork anew
        return None
    if len(head) + sum(b.raw().nbytes for b in buffers) > MAX_BYTES:
        return None
    return ScenePatch(send, keep, acc.last_update if edits else None,
                      new_ctx.lights is not old_ctx.lights, float(new_ctx.eps), fingerprint(new_ctx))


def apply(ctx, patch):
    """(twin) ctx brought to the parent's new context by ``patch``."""
    scene = object.__new__(type(ctx.scene))
    old = vars(ctx.scene)
    scene.__dict__.update({k: old[k] for k in patch.keep})
    scene.__dict__.update(patch.send)
    acc = bare(ctx.accel)
    if patch.update is not None:
        acc.replay(patch.update, scene.vertices, scene.triangles, scene.object_ids,
                   getattr(scene, "object_keys", None) or None)
    if patch.new_lights:
        lights = LightSet(scene)
    else:
        lights = ctx.lights.follow(scene)
    out = dataclasses.replace(ctx, scene=scene, accel=transparency.wrap(acc, scene), lights=lights,
                              eps=patch.eps)
    if fingerprint(out) != patch.fingerprint:
        raise RuntimeError("the twin's scene differs from the parent's")
    return out
