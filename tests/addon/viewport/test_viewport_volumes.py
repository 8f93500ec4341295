"""Volume objects in the viewport (export/volume_objects.py through the sync
of sync/reader.py): one added, its material edited and removed while a
session runs."""

import numpy as np

from support.viewport_util import build_scene, new_session, step
from support.volume_scenes import lumpy_ball, smoke_material, volume_object, write_vdb


def test_volume_object_added_edited_and_removed(vp, tmp_path):
    """A ReSTIR session path-traces once a volume object is added (the smoke
    darkens the box behind it), follows a denser material, and returns to
    ReSTIR when the object is deleted."""
    import bpy
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED")
    step(session, frames=2)
    assert not session.path_traced
    clear = session.frame[..., :3].mean()
    mat, node = smoke_material("principled")
    node.inputs["Color"].default_value = (0.1, 0.1, 0.1, 1.0)
    ob = volume_object(write_vdb(tmp_path / "ball.vdb", {"density": lumpy_ball()}), material=mat)
    ob.location, ob.scale = (-1.0, -2.0, 0.0), (1.5, 1.5, 1.5)
    bpy.context.view_layer.update()
    step(session, [(ob, True, True, False)], frames=2)
    assert session.path_traced and "volumes: path traced" in session.status()
    smoky = session.frame[..., :3].mean()
    assert np.isfinite(session.frame).all() and smoky < 0.97 * clear
    node.inputs["Density"].default_value = 8.0
    bpy.context.view_layer.update()
    step(session, [(mat, False, False, True)], frames=2)
    denser = session.frame[..., :3].mean()
    assert denser < smoky - 0.1 * (clear - smoky)
    bpy.data.objects.remove(ob)
    bpy.context.view_layer.update()
    step(session, [(bpy.context.scene, True, True, False)], frames=2)
    assert not session.path_traced
    assert session.error is None
    session.close()
