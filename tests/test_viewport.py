"""The viewport session driven headless with real depsgraphs.

bpy in background mode never calls view_update / view_draw, so these tests
build a scene from numpy arrays, edit it the way a user would, record what a
depsgraph_update_post handler sees in ``depsgraph.updates`` and feed that to
``ViewportSession.sync``. Each kind of edit must cost exactly its own work
(asserted on the session's counters), reservoirs must survive a camera move,
and the image after an object move must match a fresh export of the moved
scene.
"""

import dataclasses
import math
import time
from types import SimpleNamespace

import numpy as np
import pytest

from blender_util import Recorder

W, H = 48, 32


# ---------------------------------------------------------------- scene helpers

def add_mesh(name, verts, faces, material=None, location=(0, 0, 0), scale=(1, 1, 1)):
    import bpy
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(verts, float).tolist(), [], [[int(i) for i in f] for f in faces])
    me.update()
    if material is not None:
        me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.scale = location, scale
    bpy.context.scene.collection.objects.link(ob)
    return ob


def cube():
    v = np.array([[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)])
    f = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return v, f


def grid(n, size):
    xs = np.linspace(-size / 2, size / 2, n + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="xy")
    v = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    return v, np.stack([i, i + 1, i + n + 2, i + n + 1], axis=-1).reshape(-1, 4)


def principled(name, color):
    import bpy
    mat = bpy.data.materials.new(name)
    node = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Base Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = 1.0
    return mat


def look_at(obj, target):
    from mathutils import Vector
    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def build_scene():
    """Floor, a box, a small box that moves, a point light, a grey world, a camera."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    floor = add_mesh("Floor", *grid(4, 6.0), material=principled("Grey", (0.6, 0.6, 0.6)))
    add_mesh("Box", *cube(), material=principled("Red", (0.7, 0.2, 0.1)), location=(0, 0, 0.5))
    add_mesh("Mover", *cube(), material=principled("Blue", (0.1, 0.2, 0.7)),
             location=(1.3, -0.6, 0.3), scale=(0.6, 0.6, 0.6))
    light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    light.data.energy = 800.0
    light.data.shadow_soft_size = 0.2
    light.location = (0.5, -1.0, 3.0)
    scene.collection.objects.link(light)
    world = bpy.data.worlds.new("World")
    scene.world = world
    background = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    background.inputs["Color"].default_value = (0.1, 0.1, 0.12, 1.0)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0.0, -5.5, 3.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    look_at(cam, (0.2, 0.0, 0.3))
    del floor
    bpy.context.view_layer.update()
    return scene


@pytest.fixture
def recorder(addon):
    import bpy
    rec = Recorder()
    yield rec
    if rec in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(rec)


@pytest.fixture
def vp(addon):
    return addon.restir_addon.viewport


def depsgraph():
    import bpy
    return bpy.context.evaluated_depsgraph_get()


def new_session(vp, mode="PATH", scale="FULL", **kw):
    kw.setdefault("max_bounces", 2)
    kw.setdefault("threads", 1)
    session = vp.ViewportSession(mode=mode, scale=scale, **kw)
    session.sync(depsgraph())
    return session


def work_delta(before, after):
    """The counters that changed, and by how much."""
    a, b = dataclasses.asdict(before), dataclasses.asdict(after)
    return {k: b[k] - a[k] for k in a if b[k] != a[k]}


def keys(session):
    """The scene's (geometry, lighting) keys: what ReSTIR GI compares between
    frames to reuse visibility and to validate samples."""
    return session.scene.geometry_key(), session.scene.lighting_key()


def step(session, updates=None, frames=1):
    """sync the updates, render frames; return the counters that changed."""
    before = dataclasses.replace(session.work)
    if updates is not None:
        session.sync(depsgraph(), updates)
    for _ in range(frames):
        assert session.render_step()
    return work_delta(before, session.work)


# ---------------------------------------------------------------- tests

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


def test05_camera_move_keeps_reservoirs(vp):
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED")
    step(session, frames=4)
    assert session.last_history_found > 0.9
    camera = session.view
    moved = dataclasses.replace(camera, to_world=camera.to_world.copy())
    angle = math.radians(1.5)
    rot = np.array([[math.cos(angle), -math.sin(angle), 0], [math.sin(angle), math.cos(angle), 0], [0, 0, 1]])
    moved.to_world[:3, :3] = rot @ camera.to_world[:3, :3]
    moved.to_world[:3, 3] += (0.05, 0.0, 0.0)
    before = dataclasses.replace(session.work)
    before_keys = keys(session)
    session.set_view(moved)
    session.set_view(moved)                     # the same view again is no change
    assert session.render_step()
    assert work_delta(before, session.work) == {"camera_updates": 1, "frames": 1}
    assert session.restir.frames == 5           # not reset
    assert keys(session) == before_keys
    assert session.last_history_found > 0.7
    session.close()


def test06_view_matrices_give_the_scene_camera(vp):
    """camera_from_view of a camera's own view and projection matrices traces
    the rays the exported camera does (perspective with shift, orthographic)."""
    import bpy
    from core.camera import generate_rays
    from restir_gi.restir_addon.export.camera import export_camera
    build_scene()
    cam = bpy.data.objects["Camera"]
    xy = np.random.default_rng(3).uniform(0, 1, (50, 2)) * (W, H)
    for setup in ({}, {"shift_x": 0.1, "shift_y": -0.05, "lens": 35.0}, {"type": "ORTHO", "shift_x": 0.07}):
        for key, value in setup.items():
            setattr(cam.data, key, value)
        dg = depsgraph()
        ref = export_camera(dg, print)
        view = vp.camera_from_view(cam.matrix_world.inverted(), cam.calc_matrix_camera(dg, x=W, y=H))
        (o0, d0, t0), (o1, d1, t1) = generate_rays(ref, W, H, xy), generate_rays(view, W, H, xy)
        np.testing.assert_allclose(o1, o0, atol=1e-4)
        np.testing.assert_allclose(d1, d0, atol=1e-5)
        np.testing.assert_allclose(t1, t0, rtol=2e-3)   # clip_end from a float32 projection


def test07_resize_reallocates_without_export(vp):
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


def test08_object_move_matches_fresh_export(vp, recorder):
    """After moves (the mover in the dynamic Embree scene), the image equals a
    fresh export of the moved scene traced with the same random numbers."""
    import bpy
    from core import RenderContext, RenderSettings, render_frame
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


def test09_stops_when_converged(vp, recorder):
    import bpy
    build_scene()
    session = new_session(vp, samples=3)
    assert [session.render_step() for _ in range(4)] == [True, True, True, False]
    assert session.converged
    lamp = bpy.data.lights["Lamp"]
    session.sync(depsgraph(), recorder.edit(lambda: setattr(lamp, "energy", 900.0)))
    assert not session.converged
    assert session.render_step()
    session.close()
    restir = new_session(vp, mode="RESTIR_BIASED", idle_frames=2)
    assert [restir.render_step() for _ in range(3)] == [True, True, False]
    restir.close()


def test10_moved_objects_settle(vp, recorder):
    import bpy
    build_scene()
    session = new_session(vp, settle_frames=2, samples=100)
    step(session)
    mover = bpy.data.objects["Mover"]
    step(session, recorder.edit(lambda: setattr(mover, "location", (0.7, -0.5, 0.3))))
    assert session.accel.dynamic_keys == {("Mover", ())}
    assert step(session, frames=2) == {"accel_static_builds": 1, "frames": 2}
    assert session.accel.dynamic_keys == set()
    session.close()


def test11_objects_added_and_removed(vp, recorder):
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


def test12_thread_renders_and_close_frees(vp, recorder):
    import bpy
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED", idle_frames=10_000, threads=2)
    session.resize(160, 120)
    session.start()
    assert session.wait_for_frame(timeout=60)
    # Edits while the thread renders reach a later frame.
    mover = bpy.data.objects["Mover"]
    for x in (0.9, 0.8, 0.7):
        session.sync(depsgraph(), recorder.edit(lambda: setattr(mover, "location", (x, -0.5, 0.3))))
    assert session.wait_for_frame(session.generation, timeout=60)
    assert session.error is None
    assert session.nbytes > 0
    workers = session._ctx.workers
    assert workers.threads == 2 and workers._pool is not None     # frames use both cores
    # Closing abandons the frame in progress at its next ray batch.
    t0 = time.perf_counter()
    assert session.close(timeout=10)
    closed_in = time.perf_counter() - t0
    assert not session.running
    assert closed_in < max(0.5, 0.5 * session.last_frame_seconds)
    assert session.frame is None and session.accel is None and session.restir.history is None
    assert session.nbytes == 0
    assert workers._pool is None                                  # its threads are gone


def test13_idle_thread_does_no_work(vp):
    build_scene()
    session = new_session(vp, samples=2)
    session.start()
    deadline = time.perf_counter() + 30
    while not session.converged and time.perf_counter() < deadline:
        time.sleep(0.01)
    assert session.converged
    frames = session.work.frames
    time.sleep(0.2)
    assert session.work.frames == frames == 2
    session.set_view(dataclasses.replace(session.view, lens=session.view.lens * 1.1))
    assert session.wait_for_frame(session.generation, timeout=30)
    assert session.close()


def test14_engine_callbacks(vp):
    """view_update / view_draw / free with stand-ins for the engine and the 3D
    view, view_update called from a depsgraph handler (where depsgraph.updates
    is filled, as in a viewport); no GPU drawing in background mode."""
    import bpy
    scene = build_scene()
    scene.render.engine = "RESTIR_GI"
    scene.restir_gi.mode = "PATH"
    scene.restir_gi.max_bounces = 1
    cam = bpy.data.objects["Camera"]
    calls = []
    engine = SimpleNamespace(viewport_session=None, tag_redraw=lambda: calls.append("redraw"),
                             update_stats=lambda a, b: calls.append(b))
    dg = depsgraph()
    context = SimpleNamespace(
        region=SimpleNamespace(width=40, height=30),
        region_data=SimpleNamespace(view_matrix=cam.matrix_world.inverted(),
                                    window_matrix=cam.calc_matrix_camera(dg, x=40, y=30)))
    vp.view_update(engine, context, dg)
    session = engine.viewport_session
    assert session is not None and session.running and session.mode == "PATH"
    assert session.work.full_exports == 1
    vp.view_draw(engine, context, dg)
    assert "redraw" in calls and not any("failed" in c for c in calls)

    # Add-on settings changed in a panel: noticed at the next redraw.
    scene.restir_gi.mode = "RESTIR_BIASED"
    vp.view_draw(engine, context, dg)
    assert session.mode == "RESTIR_BIASED" and session.work.settings_updates == 1

    def handler(_scene, depsgraph):
        vp.view_update(engine, context, depsgraph)

    bpy.app.handlers.depsgraph_update_post.append(handler)
    try:
        bpy.data.lights["Lamp"].energy = 300.0
        bpy.context.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(handler)
    assert session.work.light_updates == 1 and session.work.full_exports == 1
    assert session.work.settings_updates == 1
    assert session.wait_for_frame(session.generation, timeout=60)
    vp.view_draw(engine, context, dg)
    assert not any("failed" in c for c in calls)
    vp.free(engine)
    assert engine.viewport_session is None
    assert session.close(timeout=10)               # free() did not wait; this does
    assert not session.running and session.frame is None


def test15_edit_restarts_the_frame(vp):
    """An edit abandons the frame in progress, but never two frames in a row."""
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED", idle_frames=10_000)
    session.resize(200, 150)
    session.start()
    assert session.wait_for_frame(timeout=60)
    assert session.wait_for_frame(session.generation, timeout=60)
    camera = session.view
    for i, late in enumerate((0.1, 0.4, 0.7)):
        serial = session.frame_serial
        while session.frame_serial == serial:       # just after a frame came out
            time.sleep(0.001)
        while True:                                 # early or late in the next one
            started = session._frame_started
            if started is not None and time.perf_counter() - started >= late * session.last_frame_seconds:
                break
            time.sleep(0.001)
        session.set_view(dataclasses.replace(camera, lens=camera.lens * (1.01 + 0.01 * i)))
        assert session.wait_for_frame(session.generation, timeout=60)
    assert session.error is None
    print("abandoned", session.work.abandoned_frames, "frames", session.work.frames)
    assert session.work.abandoned_frames == 3
    assert session.close()


def test16_scene_camera_and_full_resync(vp, recorder):
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
