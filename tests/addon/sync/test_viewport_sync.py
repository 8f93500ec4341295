"""The viewport session's sync of Blender data, driven headless with real
depsgraphs (helpers in viewport_util.py): each kind of edit costs exactly its
own work (asserted on the session's counters), and the image after an object
move matches a fresh export of the moved scene."""

import dataclasses

import numpy as np
import pytest

from support.viewport_util import H, W, add_mesh, build_scene, cube, depsgraph, keys, new_session, step, work_delta


def test01_first_sync_exports_everything_once(vp):
    build_scene()
    session = new_session(vp)
    assert session.work.full_exports == 1
    assert session.work.mesh_exports == 3
    assert session.render_step()
    assert session.render_size == (W, H)
    assert session.frame.shape == (H, W, 4) and session.frame.dtype == np.float32
    assert session.frame[..., :3].mean() > 0.01
    assert session.work.accel_static_builds == 1 and session.work.accel_dynamic_builds == 0
    scene = session.scene
    assert scene.triangle_count == 32 + 12 + 12
    assert len(scene.lights) == 1
    np.testing.assert_allclose(scene.environment.constant, (0.1, 0.1, 0.12), atol=1e-6)
    session.close()


def test02_transform_edit_moves_triangles_only(vp, recorder):
    import bpy
    build_scene()
    session = new_session(vp)
    step(session)
    mover = bpy.data.objects["Mover"]
    geometry, lighting = keys(session)
    updates = recorder.edit(lambda: setattr(mover, "location", (1.0, -0.4, 0.3)))
    # First move: the rest of the scene is built once without the mover.
    assert step(session, updates) == {"object_walks": 1, "transform_updates": 1, "triangle_updates": 1,
                                      "accel_static_builds": 1, "accel_dynamic_builds": 1, "frames": 1}
    # Later moves: only the mover's small Embree scene.
    for x in (0.8, 0.6):
        updates = recorder.edit(lambda: setattr(mover, "location", (x, -0.4, 0.3)))
        assert step(session, updates) == {"object_walks": 1, "transform_updates": 1, "triangle_updates": 1,
                                          "accel_dynamic_builds": 1, "frames": 1}
    g, li = keys(session)
    assert g != geometry and li != lighting
    # The triangles moved with the object.
    scene = session.scene
    oid = scene.object_keys.index(("Mover", ()))
    box = scene.vertices[np.unique(scene.triangles[scene.object_ids == oid])]
    np.testing.assert_allclose((box.min(axis=0) + box.max(axis=0)) / 2, (0.6, -0.4, 0.3), atol=1e-5)
    np.testing.assert_allclose(scene.object_matrices[oid][:3, 3], (0.6, -0.4, 0.3), atol=1e-6)
    session.close()


def test03_geometry_edit_rereads_that_mesh_only(vp, recorder):
    import bpy
    build_scene()
    session = new_session(vp)
    step(session)
    me = bpy.data.objects["Box"].data

    def raise_corner():
        me.vertices[7].co.z = 0.9
        me.update()

    delta = step(session, recorder.edit(raise_corner))
    assert delta == {"mesh_exports": 1, "object_walks": 1, "triangle_updates": 1,
                     "accel_static_builds": 1, "accel_dynamic_builds": 1, "frames": 1}
    assert np.isclose(session.scene.vertices[:, 2].max(), 0.5 + 0.9)

    # A topology change (more triangles) renumbers the combined scene.
    def subdivide():
        import bmesh
        bm = bmesh.new()
        bm.from_mesh(me)
        bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=1, use_grid_fill=True)
        bm.to_mesh(me)
        bm.free()
        me.update()

    delta = step(session, recorder.edit(subdivide))
    assert delta == {"mesh_exports": 1, "object_walks": 1, "triangle_updates": 1,
                     "accel_dynamic_builds": 1, "frames": 1}
    assert session.scene.triangle_count == 32 + 48 + 12
    session.close()


@pytest.mark.parametrize("kind", ["material", "light_energy", "light_move", "world"])
def test04_shading_edits_leave_the_triangles_alone(vp, recorder, kind):
    import bpy
    build_scene()
    session = new_session(vp)
    step(session)
    before = session.frame[..., :3].mean()
    geometry, lighting = keys(session)
    if kind == "material":
        node = bpy.data.materials["Grey"].node_tree.nodes["Principled BSDF"]
        change = lambda: setattr(node.inputs["Base Color"], "default_value", (0.9, 0.9, 0.9, 1))  # noqa: E731
        expected = {"material_updates": 1, "frames": 1}
    elif kind == "light_energy":
        change = lambda: setattr(bpy.data.lights["Lamp"], "energy", 1600.0)  # noqa: E731
        expected = {"object_walks": 1, "light_updates": 1, "frames": 1}
    elif kind == "light_move":
        change = lambda: setattr(bpy.data.objects["Lamp"], "location", (0.5, -1.0, 2.5))  # noqa: E731
        expected = {"object_walks": 1, "light_updates": 1, "frames": 1}
    else:
        bg = bpy.data.worlds["World"].node_tree.nodes["Background"]
        change = lambda: setattr(bg.inputs["Color"], "default_value", (0.3, 0.3, 0.4, 1))  # noqa: E731
        expected = {"world_updates": 1, "frames": 1}
    assert step(session, recorder.edit(change)) == expected
    assert session.frame[..., :3].mean() > before * 1.05     # each edit brightens the image
    assert keys(session)[0] == geometry and keys(session)[1] != lighting
    session.close()


def test05_resize_reallocates_without_export(vp):
    build_scene()
    session = new_session(vp, scale="HALF")
    step(session)
    assert session.frame.shape == (H // 2, W // 2, 4)
    before = dataclasses.replace(session.work)
    session.resize(W, H)                        # unchanged: nothing to do
    session.resize(64, 40)
    assert session.render_step()
    assert work_delta(before, session.work) == {"resizes": 1, "frames": 1}
    assert session.render_size == (32, 20) and session.frame.shape == (20, 32, 4)
    session.close()


def test06_object_move_matches_fresh_export(vp, recorder):
    """After moves (the mover in the dynamic Embree scene), the image equals a
    fresh export of the moved scene traced with the same random numbers."""
    import bpy
    from restir_gi.core import RenderContext, RenderSettings, render_frame
    from restir_gi.restir_addon.export import export_scene
    build_scene()
    session = new_session(vp, samples=64)
    step(session)
    mover = bpy.data.objects["Mover"]
    for x in (0.9, 0.5):
        step(session, recorder.edit(lambda: setattr(mover, "location", (x, -0.8, 0.3))))
    assert session.accel.dynamic_keys == {("Mover", ())}
    step(session, frames=3)
    fresh, _ = export_scene(depsgraph(), W, H)
    ctx = RenderContext.build(fresh)
    ref = render_frame(ctx, RenderSettings(samples=4, max_bounces=2, seed=0)).mean()
    ctx.close()
    img = session.frame[..., :3]
    same = np.isclose(img, ref, rtol=1e-4, atol=1e-5).all(axis=2)
    print("equal pixels", same.mean(), "mean ratio", img.mean() / ref.mean())
    assert same.mean() > 0.99
    assert abs(img.mean() / ref.mean() - 1) < 0.01
    session.close()


def test07_objects_added_and_removed(vp, recorder):
    import bpy
    build_scene()
    session = new_session(vp)
    step(session)
    added = recorder.edit(lambda: add_mesh("Extra", *cube(), location=(-1.5, 0.5, 0.5)))
    delta = step(session, added)
    assert delta["mesh_exports"] == 1 and delta["accel_dynamic_builds"] == 1
    assert "accel_static_builds" not in delta and "full_exports" not in delta
    assert session.scene.triangle_count == 32 + 12 + 12 + 12
    removed = recorder.edit(lambda: bpy.data.objects.remove(bpy.data.objects["Box"]))
    delta = step(session, removed)
    assert "mesh_exports" not in delta and delta["accel_static_builds"] == 1
    assert session.scene.triangle_count == 32 + 12 + 12
    assert ("Box", ()) not in session.scene.object_keys
    session.close()


def test08_scene_camera_and_full_resync(vp, recorder):
    """Without set_view the view follows the scene camera; a second full sync
    builds everything afresh (nothing left in the dynamic scene)."""
    import bpy
    build_scene()
    session = new_session(vp)
    step(session)
    cam = bpy.data.objects["Camera"]
    delta = step(session, recorder.edit(lambda: setattr(cam, "location", (0.2, -5.5, 3.0))))
    assert delta == {"object_walks": 1, "camera_updates": 1, "frames": 1}
    np.testing.assert_allclose(session.view.to_world[:3, 3], (0.2, -5.5, 3.0), atol=1e-6)
    mover = bpy.data.objects["Mover"]
    step(session, recorder.edit(lambda: setattr(mover, "location", (0.7, -0.5, 0.3))))
    assert session.accel.dynamic_keys
    delta = step(session, [])
    assert delta == {"frames": 1}                   # no updates: no work
    before = dataclasses.replace(session.work)
    session.sync(depsgraph())
    assert session.render_step()
    delta = work_delta(before, session.work)
    assert delta["full_exports"] == 1 and delta["mesh_exports"] == 3
    assert delta["accel_static_builds"] == 1 and "accel_dynamic_builds" not in delta
    assert session.accel.dynamic_keys == set()
    session.close()
