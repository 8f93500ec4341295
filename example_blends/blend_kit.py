"""Building blocks for the example and corpus scenes (``make_examples.py``,
``make_corpus.py``): an empty scene with render settings, a constant-colour
world, node materials the engine reads (Diffuse, Principled, Emission), meshes
from numpy arrays through ``foreach_set`` (no bpy.ops primitive operators),
quads, boxes, walls with a hole, lights, a camera and its keyframes, and
saving a compressed .blend next to this file.

Face winding gives normals facing the side the camera sees: callers pass the
normal they want and the helpers order the corners to match.
"""

import math
import os

import numpy as np
import bpy

HERE = os.path.dirname(os.path.abspath(__file__))


# ---------------------------------------------------------------------------
# Scene / render setup
# ---------------------------------------------------------------------------

def new_scene():
    """Start from an empty factory file and return its scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def setup_render(scene, res_x, res_y):
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x = res_x
    r.resolution_y = res_y
    r.resolution_percentage = 100
    r.film_transparent = False
    r.image_settings.file_format = 'PNG'
    r.image_settings.color_mode = 'RGB'
    r.image_settings.color_depth = '8'
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    c = scene.cycles
    c.samples = 64
    c.device = 'CPU'
    # Cycles serves as an unbiased reference: no denoiser, no adaptive stop.
    c.use_denoising = False
    c.use_adaptive_sampling = False


def set_world(scene, name, color, strength=1.0):
    world = bpy.data.worlds.new(name)
    nt = world.node_tree  # new worlds come with a node tree in 5.0
    nt.nodes.clear()
    bg = nt.nodes.new('ShaderNodeBackground')
    bg.inputs['Color'].default_value = (*color, 1.0)
    bg.inputs['Strength'].default_value = strength
    out = nt.nodes.new('ShaderNodeOutputWorld')
    out.location = (300, 0)
    nt.links.new(bg.outputs['Background'], out.inputs['Surface'])
    world.color = color  # viewport / fallback colour
    scene.world = world
    return world


# ---------------------------------------------------------------------------
# Materials
# ---------------------------------------------------------------------------

def _material(name):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree  # new materials come with a node tree in 5.0
    nt.nodes.clear()
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    out.location = (300, 0)
    return mat, nt, out


def diffuse_material(name, color):
    mat, nt, out = _material(name)
    bsdf = nt.nodes.new('ShaderNodeBsdfDiffuse')
    bsdf.inputs['Color'].default_value = (*color, 1.0)
    bsdf.inputs['Roughness'].default_value = 0.0
    nt.links.new(bsdf.outputs['BSDF'], out.inputs['Surface'])
    mat.diffuse_color = (*color, 1.0)
    return mat


def emission_material(name, color, strength):
    mat, nt, out = _material(name)
    em = nt.nodes.new('ShaderNodeEmission')
    em.inputs['Color'].default_value = (*color, 1.0)
    em.inputs['Strength'].default_value = strength
    nt.links.new(em.outputs['Emission'], out.inputs['Surface'])
    mat.diffuse_color = (*color, 1.0)
    return mat


def principled_material(name, color, roughness, metallic=0.0):
    """Principled BSDF with constant Base Color, Roughness and Metallic."""
    mat, nt, out = _material(name)
    bsdf = nt.nodes.new('ShaderNodeBsdfPrincipled')
    bsdf.inputs['Base Color'].default_value = (*color, 1.0)
    bsdf.inputs['Roughness'].default_value = roughness
    bsdf.inputs['Metallic'].default_value = metallic
    nt.links.new(bsdf.outputs['BSDF'], out.inputs['Surface'])
    mat.diffuse_color = (*color, 1.0)
    mat.roughness = roughness
    mat.metallic = metallic
    return mat


# ---------------------------------------------------------------------------
# Geometry helpers
# ---------------------------------------------------------------------------

def add_mesh(name, verts, faces, material, location=(0.0, 0.0, 0.0),
             collection=None):
    """Create a mesh object from an (N,3) vertex array and a list of faces
    (each a sequence of 3 or 4 vertex indices, counter-clockwise seen from the
    side the normal points to)."""
    verts = np.asarray(verts, dtype=np.float32).reshape(-1, 3)
    sizes = np.array([len(f) for f in faces], dtype=np.int32)
    starts = np.zeros(len(faces), dtype=np.int32)
    starts[1:] = np.cumsum(sizes)[:-1]
    corners = np.concatenate([np.asarray(f, dtype=np.int32) for f in faces])

    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set('co', verts.ravel())
    mesh.loops.add(len(corners))
    mesh.loops.foreach_set('vertex_index', corners)
    mesh.polygons.add(len(faces))
    mesh.polygons.foreach_set('loop_start', starts)
    mesh.polygons.foreach_set('loop_total', sizes)
    # Boxes and walls are faceted: flat shading, as a modeller would set it.
    mesh.polygons.foreach_set('use_smooth', [False] * len(faces))
    mesh.update()
    if mesh.validate():
        raise RuntimeError(f"mesh {name!r} was invalid and had to be fixed")
    if material is not None:
        mesh.materials.append(material)

    ob = bpy.data.objects.new(name, mesh)
    ob.location = location
    (collection or bpy.context.scene.collection).objects.link(ob)
    return ob


def quad(corners, normal):
    """Return (verts, faces) for one quad with the winding chosen so that its
    geometric normal agrees with ``normal``. Corners go round the quad."""
    c = np.asarray(corners, dtype=np.float64)
    n = np.cross(c[1] - c[0], c[2] - c[0])
    if np.dot(n, normal) < 0:
        c = c[::-1]
    return c, [[0, 1, 2, 3]]


def box_geometry(size, center=(0.0, 0.0, 0.0), rot_z_deg=0.0, inward=False):
    """8 verts / 6 quads of an axis box of ``size`` (sx, sy, sz) rotated about
    Z by ``rot_z_deg`` around its centre. Normals point outward (or inward)."""
    sx, sy, sz = (0.5 * s for s in size)
    v = np.array([[x, y, z] for z in (-sz, sz) for y in (-sy, sy)
                  for x in (-sx, sx)], dtype=np.float64)
    # index = 4*zi + 2*yi + xi ; outward CCW winding:
    faces = [
        [0, 2, 3, 1],  # bottom (-z)
        [4, 5, 7, 6],  # top    (+z)
        [0, 1, 5, 4],  # front  (-y)
        [2, 6, 7, 3],  # back   (+y)
        [0, 4, 6, 2],  # left   (-x)
        [1, 3, 7, 5],  # right  (+x)
    ]
    if inward:
        faces = [f[::-1] for f in faces]
    a = math.radians(rot_z_deg)
    rz = np.array([[math.cos(a), -math.sin(a), 0.0],
                   [math.sin(a), math.cos(a), 0.0],
                   [0.0, 0.0, 1.0]])
    v = v @ rz.T + np.asarray(center, dtype=np.float64)
    return v, faces


def merge(*parts):
    """Concatenate several (verts, faces) pairs into one."""
    verts, faces, off = [], [], 0
    for v, f in parts:
        verts.append(np.asarray(v, dtype=np.float64))
        faces.extend([[i + off for i in face] for face in f])
        off += len(v)
    return np.concatenate(verts), faces


def add_quad(name, corners, normal, material, **kw):
    v, f = quad(corners, normal)
    return add_mesh(name, v, f, material, **kw)


def add_box(name, size, center, material, rot_z_deg=0.0):
    """Box object whose origin is at the centre of its bottom face."""
    cx, cy, cz = center
    v, f = box_geometry(size, (0.0, 0.0, 0.5 * size[2]), rot_z_deg)
    return add_mesh(name, v, f, material, location=(cx, cy, cz - 0.5 * size[2]))


def add_wall_with_hole(name, axis, coord, normal, span_u, span_v, hole,
                       material):
    """Rectangular wall in the plane ``axis = coord`` with a rectangular hole.

    ``span_u``/``span_v`` are the (min, max) extents along the two in-plane
    axes (in x,y,z order with ``axis`` removed); ``hole`` is
    ((u0, u1), (v0, v1)). Built from 8 quads around the hole (a 3x3 grid
    without its centre cell), sharing vertices so there are no cracks.
    """
    us = [span_u[0], hole[0][0], hole[0][1], span_u[1]]
    vs = [span_v[0], hole[1][0], hole[1][1], span_v[1]]
    other = [i for i in range(3) if i != axis]
    verts = []
    for vv in vs:
        for uu in us:
            p = [0.0, 0.0, 0.0]
            p[axis] = coord
            p[other[0]] = uu
            p[other[1]] = vv
            verts.append(p)
    verts = np.array(verts)
    faces = []
    for j in range(3):
        for i in range(3):
            if i == 1 and j == 1:
                continue  # the opening
            a = 4 * j + i
            f = [a, a + 1, a + 5, a + 4]
            n = np.cross(verts[f[1]] - verts[f[0]], verts[f[2]] - verts[f[0]])
            if np.dot(n, normal) < 0:
                f = f[::-1]
            faces.append(f)
    return add_mesh(name, verts, faces, material)


def add_camera(name, location, rotation_deg, fov_deg, sensor_fit='AUTO'):
    cam = bpy.data.cameras.new(name)
    cam.type = 'PERSP'
    cam.sensor_fit = sensor_fit
    cam.angle = math.radians(fov_deg)
    cam.clip_start = 0.05
    cam.clip_end = 100.0
    ob = bpy.data.objects.new(name, cam)
    ob.location = location
    ob.rotation_euler = [math.radians(a) for a in rotation_deg]
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.scene.camera = ob
    return ob


def look_at_rotation(eye, target):
    """Euler XYZ (degrees) for a camera at ``eye`` looking at ``target`` with
    world +Z up (camera looks along its local -Z)."""
    d = np.asarray(target, float) - np.asarray(eye, float)
    yaw = math.degrees(math.atan2(d[1], d[0])) - 90.0
    pitch = math.degrees(math.atan2(d[2], math.hypot(d[0], d[1])))
    return (90.0 + pitch, 0.0, yaw)


def make_linear(ob):
    """Set LINEAR interpolation on all of ``ob``'s keyframes. Blender 5.0 has
    layered actions (no ``Action.fcurves``): F-curves live in channelbags.
    ``keyframe_insert`` ignores the user preference for new interpolation
    type, so this is done explicitly."""
    from bpy_extras import anim_utils
    ad = ob.animation_data
    cb = anim_utils.action_get_channelbag_for_slot(ad.action, ad.action_slot)
    for fc in cb.fcurves:
        for kp in fc.keyframe_points:
            kp.interpolation = 'LINEAR'
        fc.update()


# ---------------------------------------------------------------------------
# Lights and camera animation
# ---------------------------------------------------------------------------

def direction_rotation(direction):
    """Euler XYZ (radians) for a light that shines along ``direction`` (lights
    shine along their local -Z)."""
    from mathutils import Vector
    d = np.asarray(direction, dtype=np.float64)
    return Vector(tuple(-d / np.linalg.norm(d))).to_track_quat('Z', 'Y').to_euler()


def sun_direction(elevation_deg, azimuth_deg):
    """Unit travel direction of sunlight: along +x turned by ``azimuth_deg``
    about Z, tilted down by ``elevation_deg``."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), -math.sin(e)])


def add_light(name, kind, energy, location, direction=(0.0, 0.0, -1.0),
              color=(1.0, 1.0, 1.0), **settings):
    """Light object of ``kind`` ('POINT', 'SPOT', 'SUN', 'AREA') shining along
    ``direction``; ``settings`` are set on the light data (``size``, ``angle``,
    ``shape``, ``spot_size``, ...). Energy in Cycles' units (W, or W/m^2 for
    the sun)."""
    light = bpy.data.lights.new(name, kind)
    light.energy = energy
    light.color = color
    for key, value in settings.items():
        setattr(light, key, value)
    ob = bpy.data.objects.new(name, light)
    ob.location = location
    ob.rotation_euler = direction_rotation(direction)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def keyframe_move(ob, frame_start, frame_end, offset, rotation_deg):
    """Linear move of ``ob`` from its current pose at ``frame_start`` to the
    pose moved by ``offset`` (m) and turned by ``rotation_deg`` (Euler XYZ,
    degrees) at ``frame_end``."""
    loc0 = np.array(ob.location)
    rot0 = np.array(ob.rotation_euler)
    ob.keyframe_insert(data_path="location", frame=frame_start)
    ob.keyframe_insert(data_path="rotation_euler", frame=frame_start)
    ob.location = tuple(loc0 + np.asarray(offset, dtype=np.float64))
    ob.rotation_euler = tuple(rot0 + np.radians(rotation_deg))
    ob.keyframe_insert(data_path="location", frame=frame_end)
    ob.keyframe_insert(data_path="rotation_euler", frame=frame_end)
    ob.location, ob.rotation_euler = tuple(loc0), tuple(rot0)
    make_linear(ob)


def register_engine():
    """Register the engine from this source tree, so the files can carry its
    settings (stored with the scene, read when the extension is installed)."""
    import importlib.util
    import sys
    root = os.path.dirname(HERE)
    if "restir_gi" not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            "restir_gi", os.path.join(root, "__init__.py"), submodule_search_locations=[root])
        module = importlib.util.module_from_spec(spec)
        sys.modules["restir_gi"] = module
        spec.loader.exec_module(module)
        module.register()


def use_restir(scene, max_bounces=None, warmup_frames=16, mode="RESTIR_BIASED"):
    """Store ReSTIR GI settings in the scene (default: biased, the engine's
    bounce limits, which are Cycles', as the animated example renders)."""
    register_engine()
    s = scene.restir_gi
    s.mode = mode
    s.samples = 1
    if max_bounces is not None:
        s.max_bounces = max_bounces
    s.warmup_frames = warmup_frames


def save(name):
    """Save the open file under example_blends/, every scene set to render
    with ReSTIR GI (the engine of the dropdown when a user opens it)."""
    register_engine()
    for scene in bpy.data.scenes:
        scene.render.engine = "RESTIR_GI"
    path = os.path.join(HERE, name)
    # Overwriting would leave a "<name>.blend1" backup next to the file.
    for p in (path, path + "1"):
        if os.path.exists(p):
            os.remove(p)
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True)
    print(f"wrote {path} ({os.path.getsize(path)} bytes)")
    return path
