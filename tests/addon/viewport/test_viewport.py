"""The viewport session's frames, driven headless with real depsgraphs
(helpers in viewport_util.py; what each edit costs: test_viewport_sync.py):
reservoirs survive a camera move, the view gives the scene camera, the render
thread stops when converged, idles without work, restarts a frame on an edit,
and the engine's callbacks draw what it rendered."""

import dataclasses
import math
import time
from types import SimpleNamespace

import numpy as np

from support.viewport_util import H, W, build_scene, depsgraph, keys, new_session, step, work_delta


def test01_camera_move_keeps_reservoirs(vp):
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


def test02_view_matrices_give_the_scene_camera(vp):
    """camera_from_view of a camera's own view and projection matrices traces
    the rays the exported camera does (perspective with shift, orthographic)."""
    import bpy
    from restir_gi.core.camera.projection import generate_rays
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


def test03_stops_when_converged(vp, recorder):
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
    restir = new_session(vp, mode="RESTIR_BIASED", samples=2)
    assert [restir.render_step() for _ in range(3)] == [True, True, False]
    restir.close()


def test04_moved_objects_settle(vp, recorder):
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


def test05_thread_renders_and_close_frees(vp, recorder):
    import bpy
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED", samples=0, threads=2)
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


def test06_idle_thread_does_no_work(vp):
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


def test07_engine_callbacks(vp, vp_draw):
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
    vp_draw.view_update(engine, context, dg)
    session = engine.viewport_session
    assert session is not None and session.running and session.mode == "PATH"
    assert session.work.full_exports == 1
    vp_draw.view_draw(engine, context, dg)
    assert not any("failed" in c for c in calls)
    assert "redraw" not in calls            # the next draw comes from redraw.py's watcher

    # Add-on settings changed in a panel: noticed at the next redraw.
    scene.restir_gi.mode = "RESTIR_BIASED"
    vp_draw.view_draw(engine, context, dg)
    assert session.mode == "RESTIR_BIASED" and session.work.settings_updates == 1

    def handler(_scene, depsgraph):
        vp_draw.view_update(engine, context, depsgraph)

    bpy.app.handlers.depsgraph_update_post.append(handler)
    try:
        bpy.data.lights["Lamp"].energy = 300.0
        bpy.context.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(handler)
    assert session.work.light_updates == 1 and session.work.full_exports == 1
    assert session.work.settings_updates == 1
    assert session.wait_for_frame(session.generation, timeout=60)
    vp_draw.view_draw(engine, context, dg)
    assert not any("failed" in c for c in calls)
    vp_draw.free(engine)
    assert engine.viewport_session is None
    assert session.close(timeout=10)               # free() did not wait; this does
    assert not session.running and session.frame is None


def test08_edit_restarts_the_frame(vp):
    """An edit abandons the frame in progress, but never two frames in a row."""
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED", samples=0)
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


def test09_volumes_are_path_traced_in_the_restir_modes(vp):
    """A world volume in a ReSTIR mode: the viewport path-traces its frames,
    as final renders do, says so in the header, and its image is the Path
    Tracing session's (the same seed and samples); a ReSTIR frame would
    leave the fog out."""
    import bpy
    build_scene()
    restir = new_session(vp, mode="RESTIR_BIASED")
    step(restir, frames=2)
    clear = restir.frame[..., :3].mean()
    assert not restir.path_traced and "volumes" not in restir.status()
    restir.close()
    tree = bpy.context.scene.world.node_tree
    fog = tree.nodes.new("ShaderNodeVolumeAbsorption")
    fog.inputs["Density"].default_value = 0.3
    tree.links.new(fog.outputs[0], next(n for n in tree.nodes if n.type == "OUTPUT_WORLD").inputs["Volume"])
    images = {}
    for mode in ("RESTIR_BIASED", "PATH"):
        session = new_session(vp, mode=mode)
        step(session, frames=2)
        assert session.path_traced
        images[mode] = session.frame[..., :3].copy()
        if mode != "PATH":
            assert "volumes: path traced" in session.status()
        session.close()
    assert np.isfinite(images["PATH"]).all()
    np.testing.assert_allclose(images["RESTIR_BIASED"], images["PATH"], atol=1e-6)
    assert images["PATH"].mean() < 0.8 * clear          # the fog absorbs
