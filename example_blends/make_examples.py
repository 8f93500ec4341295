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
primitive operators; the helpers are in ``blend_kit.py``). Face winding gives
normals facing the side the camera sees: into the room / box interior for
walls, outward for boxes. ``make_corpus.py`` builds the benchmark corpus,
reusing the room of ``build_room``.
"""

import math

import numpy as np
import bpy

from blend_kit import (add_box, add_camera, add_mesh, add_quad, add_wall_with_hole,
                       box_geometry, diffuse_material, emission_material, look_at_rotation,
                       make_linear, merge, new_scene, principled_material, save, set_world,
                       setup_render, use_restir)


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
