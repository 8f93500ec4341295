"""The first stage of a ReSTIR frame: what changed in the scene since the
last frame (core/restir/frame.py), and what the stream remembers to tell."""

import time
from dataclasses import dataclass

from .reservoirs import cap_history, distinct
from .temporal import ObjectMotion, carry_with_objects
from .timings import stage
from .validation import validate


@dataclass
class SceneChanges:
    """What a stream of frames remembers of its scene to see what changed:
    the scene's keys at the last frame, and what happened since the last
    sample validation."""
    lighting_key: object = None     # Scene.lighting_key of the last frame
    shading_key: object = None      # Scene.shading_key of the last frame
    geometry_key: object = None     # Scene.geometry_key of the last frame
    stale: bool = False             # the lighting changed since the last validation
    light_edit: bool = False        # lights, materials or the world changed since the last validation
    validations: int = 0            # sample validations run (skipped while nothing changed)


def scene_changes(s):
    """Objects that moved carry their samples and owners; what changed in the
    scene decides what the running means forget; after a lighting change,
    stored samples are re-traced (validation.py) every validation_interval
    frames."""
    t = time.perf_counter()
    ctx, settings, history, changes = s.ctx, s.settings, s.history, s.changes
    scene = ctx.scene
    with stage("object motion"):
        if history is not None:
            carry_with_objects(scene, history)     # samples and owners ride with moved objects
        s.motion = ObjectMotion.between(scene, history)

    # Last frame's traced visibility is reused only if no triangle moved.
    geometry_key = scene.geometry_key()
    s.moved = history is not None and geometry_key != changes.geometry_key
    s.static = history is not None and history.visibility is not None and not s.moved
    changes.geometry_key = geometry_key
    # What the pixels' running means forget (accumulation.py): everything
    # after an edit of lights, materials or the world (in the same frame as
    # objects moved too: the lights' edit lit the whole image anew), and
    # again when validation brings the stored samples up to date with that
    # edit; all but the last MOVING_CAP frames when objects moved or samples
    # were validated after objects moved (local changes: shadows, reflections).
    if settings.validation_interval > 0 or s.accumulating:
        shading_key = scene.shading_key()
        key = scene.lighting_key(geometry_key, shading_key)
        relit = changes.lighting_key is not None and key != changes.lighting_key
        changes.stale |= relit
        changes.lighting_key = key
        reshaded = changes.shading_key is not None and shading_key != changes.shading_key
        changes.shading_key = shading_key
        s.forget_all = (relit and not s.moved) or reshaded
        changes.light_edit |= s.forget_all
        s.forget_old = s.moved
    # Stored samples are re-traced only if the lighting changed since the
    # last validation: in an unchanged scene a re-traced path (same seed)
    # gives exactly its stored radiance.
    if settings.validation_interval > 0 and history is not None and changes.stale \
            and (s.index % settings.validation_interval == 0 or settings.validate_on_change):
        with stage("sample validation"):
            validate(ctx, distinct(history.temporal, history.spatial), settings.max_bounces)
        changes.validations += 1
        changes.stale = False
        if changes.light_edit:
            # Samples found under the old light stand for one candidate
            # each: a spot widened from 20 to 120 degrees left frames 7-12 %
            # dark for 14 frames while reservoirs of M up to the caps
            # outweighed the new light's samples (2-3 % with this).
            for res in distinct(history.temporal, history.spatial):
                cap_history(res, 1.0)
        s.forget_all |= changes.light_edit
        s.forget_old = True
        changes.light_edit = False
    s.timings.spent("validation", t)
