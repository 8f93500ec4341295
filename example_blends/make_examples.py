"""Build the example scenes for the ReSTIR GI render engine.

Run from anywhere:

    .venv/bin/python example_blends/make_examples.py

Writes, next to this script:

* ``cornell_box.blend``   - classic Cornell box lit by an emissive ceiling quad
                            ("CeilingLight"), black world, 256x256.
* ``room_indirect.blend`` - closed 6 x 4 x 3 m room lit only through a
                            0.8 x 0.8 m window by a Sun ("Sun") plus a dim blue
                            sky; most of the view is lit indirectly. 320x180.
* ``room_animated.blend`` - the same room, frames 1-24, with a keyframed camera
                            dolly/pan and a box ("MovingBox") sliding 1 m.

All geometry is built from numpy arrays with ``foreach_set`` (no bpy.ops
primitive operators). Face winding gives normals facing the side the camera
sees: into the room / box interior for walls, outward for boxes.
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


def principled_material(name, color, roughness):
    mat, nt, out = _material(name)
    bsdf = nt.nodes.new('ShaderNodeBsdfPrincipled')
    bsdf.inputs['Base Color'].default_value = (*color, 1.0)
    bsdf.inputs['Roughness'].default_value = roughness
    bsdf.inputs['Metallic'].default_value = 0.0
    nt.links.new(bsdf.outputs['BSDF'], out.inputs['Surface'])
    mat.diffuse_color = (*color, 1.0)
    mat.roughness = roughness
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


def use_restir(scene):
    """The animated example renders with ReSTIR GI (biased), two-bounce GI."""
    register_engine()
    s = scene.restir_gi
    s.mode = "RESTIR_BIASED"
    s.samples = 1
    s.max_bounces = 2
    s.warmup_frames = 16


def save(name):
    path = os.path.join(HERE, name)
    # Overwriting would leave a "<name>.blend1" backup next to the file.
    for p in (path, path + "1"):
        if os.path.exists(p):
            os.remove(p)
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True)
    print(f"wrote {path} ({os.path.getsize(path)} bytes)")
    return path


# ---------------------------------------------------------------------------
# 1. Cornell box
# ---------------------------------------------------------------------------

def build_cornell_box():
    scene = new_scene()
    scene.name = "CornellBox"
    setup_render(scene, 256, 256)
    scene.frame_start = scene.frame_end = scene.frame_current = 1
    set_world(scene, "BlackWorld", (0.0, 0.0, 0.0), 1.0)

    white = diffuse_material("White", (0.8, 0.8, 0.8))
    red = diffuse_material("Red", (0.8, 0.1, 0.1))
    green = diffuse_material("Green", (0.1, 0.8, 0.1))
    light = emission_material("LightEmission", (1.0, 1.0, 1.0), 15.0)

    # Box x,y in [-1,1], z in [0,2], open toward -y (the camera).
    add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
             (0, 0, 1), white)
    add_quad("Ceiling", [(-1, -1, 2), (1, -1, 2), (1, 1, 2), (-1, 1, 2)],
             (0, 0, -1), white)
    add_quad("BackWall", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)],
             (0, -1, 0), white)
    add_quad("LeftWall", [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)],
             (1, 0, 0), red)
    add_quad("RightWall", [(1, -1, 0), (1, 1, 0), (1, 1, 2), (1, -1, 2)],
             (-1, 0, 0), green)

    add_box("TallBox", (0.6, 0.6, 1.2), (-0.33, 0.3, 0.6), white, rot_z_deg=-17.0)
    add_box("ShortBox", (0.6, 0.6, 0.6), (0.35, -0.35, 0.3), white, rot_z_deg=17.0)

    # Emissive 0.5 x 0.5 m quad 1 cm below the ceiling, facing down.
    h, z = 0.25, 1.99
    add_quad("CeilingLight", [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)],
             (0, 0, -1), light, location=(0.0, 0.0, z))

    add_camera("Camera", (0.0, -3.9, 1.0), (90.0, 0.0, 0.0), 38.0)
    return save("cornell_box.blend")


# ---------------------------------------------------------------------------
# 2./3. Room lit through a window
# ---------------------------------------------------------------------------

ROOM_X = (-3.0, 3.0)   # 6 m
ROOM_Y = (-2.0, 2.0)   # 4 m
ROOM_Z = (0.0, 3.0)    # 3 m
# Window in the -x wall: 0.8 x 0.8 m, centred at y = 0.3, z = 2.0.
WINDOW_Y = (-0.1, 0.7)
WINDOW_Z = (1.6, 2.4)
# Sun travels +x and downward, elevation 40 deg, slightly toward -y: the
# 0.8 x 0.8 window throws a bright patch on the floor around x ~ -0.6.
SUN_ELEVATION = 40.0
SUN_AZIMUTH = -15.0    # rotation of the travel direction about Z from +x
SUN_STRENGTH = 100.0   # W/m^2 (irradiance); high so the indirect light is mid-grey
SUN_ANGLE = 1.0        # degrees
SKY_COLOR = (0.35, 0.5, 0.8)
SKY_STRENGTH = 1.0

CAM_START = (-2.55, -1.65, 1.65)
CAM_TARGET = (0.1, 0.4, 0.3)
CAM_FOV = 75.0         # horizontal, degrees


def sun_rotation():
    """Euler XYZ (radians) for a sun (which shines along its local -Z)
    travelling along +x tilted down by SUN_ELEVATION and turned by
    SUN_AZIMUTH about Z."""
    e = math.radians(SUN_ELEVATION)
    a = math.radians(SUN_AZIMUTH)
    d = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a),
                  -math.sin(e)])
    from mathutils import Vector
    return Vector((-d[0], -d[1], -d[2])).to_track_quat('Z', 'Y').to_euler(), d


def build_room(scene):
    setup_render(scene, 320, 180)
    set_world(scene, "SkyWorld", SKY_COLOR, SKY_STRENGTH)

    wall = diffuse_material("WallWhite", (0.8, 0.8, 0.8))
    ceiling = diffuse_material("CeilingWhite", (0.85, 0.85, 0.85))
    floor = principled_material("FloorGlossy", (0.7, 0.6, 0.5), 0.4)
    orange = diffuse_material("BoxOrange", (0.8, 0.4, 0.15))
    blue = diffuse_material("BoxBlue", (0.15, 0.3, 0.75))
    wood = diffuse_material("TableWood", (0.45, 0.3, 0.18))

    (x0, x1), (y0, y1), (z0, z1) = ROOM_X, ROOM_Y, ROOM_Z
    add_quad("Floor", [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)],
             (0, 0, 1), floor)
    add_quad("Ceiling", [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
             (0, 0, -1), ceiling)
    add_quad("BackWall", [(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)],
             (0, -1, 0), wall)
    add_quad("FrontWall", [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
             (0, 1, 0), wall)
    add_quad("RightWall", [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],
             (-1, 0, 0), wall)
    add_wall_with_hole("WindowWall", 0, x0, (1, 0, 0), ROOM_Y, ROOM_Z,
                       (WINDOW_Y, WINDOW_Z), wall)

    # Furniture.
    add_box("BoxBlue", (0.7, 0.7, 0.7), (1.6, 1.1, 0.35), blue, rot_z_deg=20.0)
    add_box("CabinetTall", (0.5, 0.8, 1.6), (2.6, -1.3, 0.8), wood, rot_z_deg=0.0)
    top_h, leg = 0.72, 0.06
    table = merge(
        box_geometry((1.4, 0.8, 0.05), (0.0, 0.0, top_h - 0.025)),
        *[box_geometry((leg, leg, top_h - 0.05),
                       (sx * 0.62, sy * 0.32, 0.5 * (top_h - 0.05)))
          for sx in (-1, 1) for sy in (-1, 1)])
    add_mesh("Table", table[0], table[1], wood, location=(0.9, -0.6, 0.0))
    moving = add_box("MovingBox", (0.45, 0.45, 0.45), (-0.6, 1.0, 0.225),
                     orange, rot_z_deg=10.0)

    rot, d = sun_rotation()
    sun = bpy.data.lights.new("Sun", 'SUN')
    sun.energy = SUN_STRENGTH
    sun.angle = math.radians(SUN_ANGLE)
    sun.color = (1.0, 0.95, 0.88)
    sun_ob = bpy.data.objects.new("Sun", sun)
    # Outside the window, on the line through the window centre.
    wc = np.array([x0, 0.5 * sum(WINDOW_Y), 0.5 * sum(WINDOW_Z)])
    sun_ob.location = tuple(wc - 3.0 * d)
    sun_ob.rotation_euler = rot
    scene.collection.objects.link(sun_ob)

    cam = add_camera("Camera", CAM_START, look_at_rotation(CAM_START, CAM_TARGET),
                     CAM_FOV, sensor_fit='HORIZONTAL')
    return cam, moving


def build_room_indirect():
    scene = new_scene()
    scene.name = "RoomIndirect"
    scene.frame_start = scene.frame_end = scene.frame_current = 1
    build_room(scene)
    return save("room_indirect.blend")


def build_room_animated():
    scene = new_scene()
    scene.name = "RoomAnimated"
    scene.frame_start, scene.frame_end = 1, 24
    scene.render.fps = 24
    cam, moving = build_room(scene)

    # Camera: 30 cm dolly sideways/forward and a 4 degree pan to the left.
    start_loc = np.array(CAM_START)
    start_rot = np.array(cam.rotation_euler)
    scene.frame_set(1)
    cam.location = tuple(start_loc)
    cam.rotation_euler = tuple(start_rot)
    cam.keyframe_insert(data_path="location", frame=1)
    cam.keyframe_insert(data_path="rotation_euler", frame=1)
    cam.location = tuple(start_loc + np.array([0.25, 0.15, -0.05]))
    cam.rotation_euler = tuple(start_rot + np.radians([-1.0, 0.0, 4.0]))
    cam.keyframe_insert(data_path="location", frame=24)
    cam.keyframe_insert(data_path="rotation_euler", frame=24)

    # MovingBox: slides 1 m along -y into the sun patch, turning a bit.
    loc0 = np.array(moving.location)
    rot0 = np.array(moving.rotation_euler)
    moving.keyframe_insert(data_path="location", frame=1)
    moving.keyframe_insert(data_path="rotation_euler", frame=1)
    moving.location = tuple(loc0 + np.array([0.0, -1.0, 0.0]))
    moving.rotation_euler = tuple(rot0 + np.radians([0.0, 0.0, 15.0]))
    moving.keyframe_insert(data_path="location", frame=24)
    moving.keyframe_insert(data_path="rotation_euler", frame=24)

    make_linear(cam)
    make_linear(moving)
    scene.frame_set(1)
    use_restir(scene)
    return save("room_animated.blend")


def main():
    build_cornell_box()
    build_room_indirect()
    build_room_animated()


if __name__ == "__main__":
    main()
