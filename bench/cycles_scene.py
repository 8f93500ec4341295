"""Tiny Cycles scenes built in code for bench/cycles_conventions.py: numpy +
foreach_set meshes, an orthographic camera, one emitter, rendered with Cycles
on the CPU (2 fixed threads, no denoising, no adaptive sampling) into a 32-bit
linear EXR that is read back."""

import math
import os
import tempfile

import numpy as np
import bpy

RES = 24  # image is RES x RES pixels
SPP = 128  # samples per pixel
ALBEDO = 0.8  # Diffuse BSDF colour of the receiver plane
PATCH = 0.02  # orthographic scale [m] of the receiver patch seen by the camera

TMP = tempfile.mkdtemp(prefix="cycles_conventions_")


# --------------------------------------------------------------------------- scene


def new_scene(max_bounces=0, spp=SPP):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    c = sc.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = max_bounces
    c.seed = 0
    sc.render.threads_mode = "FIXED"
    sc.render.threads = 2
    sc.render.resolution_x = RES
    sc.render.resolution_y = RES
    sc.render.resolution_percentage = 100
    sc.view_settings.view_transform = "Standard"
    im = sc.render.image_settings
    im.file_format = "OPEN_EXR"
    im.color_depth = "32"
    im.color_mode = "RGB"
    sc.world = make_world((0.0, 0.0, 0.0), 0.0)
    return sc


def make_world(color, strength):
    w = bpy.data.worlds.new("World")
    bg = next(n for n in w.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    return w


def add_quad(sc, name, size_x, size_y, z=0.0, material=None, normal_up=True):
    """Axis-aligned rectangle centred on the Z axis at height z."""
    hx, hy = 0.5 * size_x, 0.5 * size_y
    co = np.array([[-hx, -hy, z], [hx, -hy, z], [hx, hy, z], [-hx, hy, z]], np.float32)
    order = np.array([0, 1, 2, 3] if normal_up else [0, 3, 2, 1], np.int32)
    me = bpy.data.meshes.new(name)
    me.vertices.add(4)
    me.vertices.foreach_set("co", co.ravel())
    me.loops.add(4)
    me.loops.foreach_set("vertex_index", order)
    me.polygons.add(1)
    me.polygons.foreach_set("loop_start", np.array([0], np.int32))
    me.polygons.foreach_set("loop_total", np.array([4], np.int32))
    me.update(calc_edges=True)
    if material is not None:
        me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    sc.collection.objects.link(ob)
    return ob


def material(kind, color=(1.0, 1.0, 1.0), strength=1.0, roughness=0.0):
    m = bpy.data.materials.new(kind)
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if kind == "diffuse":
        n = nt.nodes.new("ShaderNodeBsdfDiffuse")
        n.inputs["Color"].default_value = (*color, 1.0)
    elif kind == "emission":
        n = nt.nodes.new("ShaderNodeEmission")
        n.inputs["Color"].default_value = (*color, 1.0)
        n.inputs["Strength"].default_value = strength
    elif kind == "principled_emission":
        n = nt.nodes.new("ShaderNodeBsdfPrincipled")
        n.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        n.inputs["Emission Color"].default_value = (*color, 1.0)
        n.inputs["Emission Strength"].default_value = strength
    elif kind == "mirror":
        n = nt.nodes.new("ShaderNodeBsdfGlossy")
        n.inputs["Color"].default_value = (*color, 1.0)
        n.inputs["Roughness"].default_value = roughness
    else:
        raise ValueError(kind)
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    return m


def add_camera(sc, z, look_up=False, scale=PATCH):
    cam = bpy.data.cameras.new("Camera")
    cam.type = "ORTHO"
    cam.ortho_scale = scale
    cam.clip_start = 1e-3
    cam.clip_end = 1e3
    ob = bpy.data.objects.new("Camera", cam)
    ob.location = (0.0, 0.0, z)
    ob.rotation_euler = (math.pi, 0.0, 0.0) if look_up else (0.0, 0.0, 0.0)
    sc.collection.objects.link(ob)
    sc.camera = ob
    return ob


def add_light(sc, kind, location, rotation=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0),
              visible_camera=None, **props):
    data = bpy.data.lights.new(kind, kind)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(kind, data)
    ob.location = location
    ob.rotation_euler = rotation
    ob.scale = scale
    if visible_camera is not None:
        ob.visible_camera = visible_camera
    sc.collection.objects.link(ob)
    return ob


def receiver(sc, z_cam=0.5):
    """Large white-ish diffuse plane at z = 0 and a camera looking straight down at it."""
    add_quad(sc, "Receiver", 20.0, 20.0, 0.0, material("diffuse", (ALBEDO,) * 3))
    add_camera(sc, z_cam)


# --------------------------------------------------------------------------- render


def read_exr(path):
    try:
        import OpenEXR

        with OpenEXR.File(path) as f:
            ch = f.channels()
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, np.float64)
            return np.stack([np.asarray(ch[c].pixels, np.float64) for c in "RGB"], -1)
    except ImportError:
        img = bpy.data.images.load(path)
        px = np.empty(len(img.pixels), np.float32)
        img.pixels.foreach_get(px)
        w, h = img.size
        out = px.reshape(h, w, img.channels)[::-1, :, :3].astype(np.float64)
        bpy.data.images.remove(img)
        return out


def render(sc):
    path = os.path.join(TMP, "render.exr")
    sc.render.filepath = path
    bpy.ops.render.render(write_still=True)
    return read_exr(path)


def pixel_centres(scale=PATCH):
    """World x, y of the pixel centres of the downward orthographic camera."""
    t = ((np.arange(RES) + 0.5) / RES - 0.5) * scale
    return np.meshgrid(t, t)
