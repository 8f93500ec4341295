"""Build the benchmark corpus for ``bench/equal_time.py``.

Run from anywhere:

    .venv/bin/python example_blends/make_corpus.py [name ...]

Writes ``corpus_<name>.blend`` next to this script (all six by default):

* ``room``       - the window room of ``make_examples.build_room`` (sun through
                   a 0.8 m window, blue sky), most of the view lit indirectly.
* ``movers``     - the room with its box sliding 1 m into the sun patch over
                   the 32 frames (turning 15 degrees): light that changes
                   around a moving object and stays put elsewhere.
* ``slit``       - closed 5 x 5 x 3 m room lit only by a sun through a 15 cm
                   roof slit; a thin sunlit stripe over the floor and a white
                   block, everything else indirect; dark world outside.
* ``glossy``     - interior with a glossy dielectric floor, metal wall panels
                   and metal / rough dielectric objects, lit by a ceiling area
                   light and a sun through a window.
* ``courtyard``  - open-top courtyard under a sun and a bright sky-blue world,
                   boxes and pillars casting shadows, a covered arcade along
                   the back lit indirectly.
* ``emitters``   - a room lit only by 32 small emissive boxes of various
                   colours (Emission shader); no lights, black world.

Common to all: 320x180, frames 1-32 with a linear keyframed camera move (a
dolly of 20-40 cm and a pan of a few degrees; nothing else moves but the
movers' box), Blender's
default pixel filter (Blackman-Harris, 1.5 px). Cycles keeps its default bounce
limits (total 12, diffuse 4, glossy 4) but with ``sample_clamp_indirect = 0``
and ``blur_glossy = 0`` (both default on and biased), and denoising and
adaptive sampling off, so Cycles is unbiased and comparable with the engine.
The engine's settings (``scene.restir_gi``): ReSTIR GI biased, Cycles' bounce
limits (total 12, diffuse 4, glossy 4, transmission 12), 16 warm-up frames.

Only what the engine supports: Diffuse, Principled (constant inputs) and
Emission materials, point / spot / sun / area lights, a world made of one
Background node of constant colour.
"""

import sys

import numpy as np

from blend_kit import (add_box, add_camera, add_light, add_mesh, add_quad, add_wall_with_hole,
                       box_geometry, diffuse_material, emission_material, keyframe_move,
                       look_at_rotation, merge, new_scene, principled_material, save, set_world,
                       setup_render, sun_direction, use_restir)
import make_examples

FRAMES = 32


def corpus_scene(name):
    scene = new_scene()
    scene.name = name
    scene.frame_start, scene.frame_end = 1, FRAMES
    scene.render.fps = 24
    setup_render(scene, 320, 180)
    c = scene.cycles
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    return scene


def finish(scene, cam, offset, rotation_deg, filename):
    keyframe_move(cam, 1, FRAMES, offset, rotation_deg)
    scene.frame_set(1)
    use_restir(scene, max_bounces=12, warmup_frames=16)
    return save(filename)


def room_shell(x, y, z, materials, skip=()):
    """Inward-facing floor, ceiling and four walls of the box x * y * z, each
    (min, max); ``materials`` maps floor / ceiling / walls (or a wall name) to
    a material; names in ``skip`` are left out (built by the caller)."""
    (x0, x1), (y0, y1), (z0, z1) = x, y, z
    parts = {
        "Floor": ([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], (0, 0, 1)),
        "Ceiling": ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, -1)),
        "BackWall": ([(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, -1, 0)),
        "FrontWall": ([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, 1, 0)),
        "LeftWall": ([(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (1, 0, 0)),
        "RightWall": ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (-1, 0, 0)),
    }
    for name, (corners, normal) in parts.items():
        if name in skip:
            continue
        kind = name.lower() if name in ("Floor", "Ceiling") else "walls"
        add_quad(name, corners, normal, materials.get(name, materials.get(kind)))


def build_room():
    scene = corpus_scene("CorpusRoom")
    cam, _box = make_examples.build_room(scene)
    # As room_animated: a 30 cm dolly sideways/forward and a 4 degree pan.
    return finish(scene, cam, (0.25, 0.15, -0.05), (-1.0, 0.0, 4.0), "corpus_room.blend")


def build_movers():
    scene = corpus_scene("CorpusMovers")
    cam, box = make_examples.build_room(scene)
    # The room's box slides 1 m into the sun patch, turning 15 degrees, as in
    # room_animated but over the corpus's 32 frames: light that changes where
    # an object moves, and stays put elsewhere.
    keyframe_move(box, 1, FRAMES, (0.0, -1.0, 0.0), (0.0, 0.0, 15.0))
    return finish(scene, cam, (0.25, 0.15, -0.05), (-1.0, 0.0, 4.0), "corpus_movers.blend")


def build_slit():
    scene = corpus_scene("CorpusSlit")
    set_world(scene, "DarkSky", (0.04, 0.05, 0.07), 1.0)
    x, y, z = (-2.5, 2.5), (-2.5, 2.5), (0.0, 3.0)
    walls = diffuse_material("WallWhite", (0.8, 0.8, 0.8))
    floor = diffuse_material("FloorGrey", (0.55, 0.55, 0.55))
    warm = diffuse_material("WallTerracotta", (0.75, 0.38, 0.22))
    block = diffuse_material("BlockWhite", (0.85, 0.85, 0.85))
    room_shell(x, y, z, {"floor": floor, "walls": walls, "LeftWall": warm}, skip=("Ceiling",))
    # Roof with a 15 cm x 4.6 m slit along y.
    add_wall_with_hole("SlitRoof", 2, z[1], (0, 0, -1), x, y, ((-0.675, -0.525), (-2.3, 2.3)), walls)
    add_box("WhiteBlock", (1.0, 1.0, 0.8), (0.2, 0.4, 0.4), block, rot_z_deg=25.0)
    d = sun_direction(62.0, 8.0)
    add_light("Sun", "SUN", 170.0, (-0.6, 0.0, 6.0), d, color=(1.0, 0.96, 0.9),
              angle=np.radians(0.8))
    eye, target = (-2.15, -2.2, 1.55), (1.0, 1.2, 0.7)
    cam = add_camera("Camera", eye, look_at_rotation(eye, target), 78.0, sensor_fit='HORIZONTAL')
    return finish(scene, cam, (0.22, 0.12, 0.0), (0.0, 0.0, 3.5), "corpus_slit.blend")


def build_glossy():
    scene = corpus_scene("CorpusGlossy")
    set_world(scene, "Sky", (0.3, 0.45, 0.7), 0.4)
    x, y, z = (-3.0, 3.0), (-2.5, 2.5), (0.0, 3.0)
    walls = diffuse_material("WallWhite", (0.75, 0.75, 0.75))
    floor = principled_material("FloorGlossy", (0.45, 0.3, 0.2), 0.25)
    steel = principled_material("Steel", (0.75, 0.76, 0.78), 0.3, metallic=1.0)
    copper = principled_material("Copper", (0.95, 0.62, 0.48), 0.35, metallic=1.0)
    gold = principled_material("Gold", (1.0, 0.8, 0.4), 0.22, metallic=1.0)
    red = principled_material("RedLacquer", (0.7, 0.08, 0.06), 0.3)
    blue = principled_material("BluePlastic", (0.1, 0.2, 0.55), 0.4)
    x0, y1 = x[0], y[1]
    room_shell(x, y, z, {"floor": floor, "ceiling": walls, "walls": walls}, skip=("LeftWall",))
    add_wall_with_hole("WindowWall", 0, x0, (1, 0, 0), y, z, ((-1.2, -0.2), (1.0, 2.2)), walls)
    # Metal panels 2 cm in front of the back wall.
    for i, (mat, u0, u1) in enumerate(((steel, -2.4, -1.0), (copper, -0.7, 0.7), (gold, 1.0, 2.4))):
        yb = y1 - 0.02
        add_quad(f"Panel{i}", [(u0, yb, 0.4), (u1, yb, 0.4), (u1, yb, 2.4), (u0, yb, 2.4)],
                 (0, -1, 0), mat)
    add_box("SteelBox", (0.8, 0.8, 0.8), (1.3, 0.9, 0.4), steel, rot_z_deg=30.0)
    add_box("RedBox", (0.7, 0.7, 1.1), (-0.6, 1.2, 0.55), red, rot_z_deg=-15.0)
    add_box("BluePlinth", (1.0, 0.6, 0.45), (0.4, -0.6, 0.225), blue, rot_z_deg=10.0)
    add_box("CopperPillar", (0.3, 0.3, 2.2), (2.4, -1.4, 1.1), copper)
    sphere_like = merge(*[box_geometry((0.35, 0.35, 0.35), (0.0, 0.0, 0.175 + 0.35 * k), 20.0 * k)
                          for k in range(3)])
    add_mesh("GoldStack", sphere_like[0], sphere_like[1], gold, location=(0.4, -0.6, 0.45))
    add_light("CeilingLight", "AREA", 120.0, (0.5, 0.0, 2.95), (0, 0, -1), size=1.2)
    d = sun_direction(35.0, 20.0)
    add_light("Sun", "SUN", 14.0, (x0 - 3.0, -0.7, 3.5), d, color=(1.0, 0.94, 0.85),
              angle=np.radians(1.0))
    eye, target = (-2.4, -2.1, 1.6), (0.6, 1.6, 0.9)
    cam = add_camera("Camera", eye, look_at_rotation(eye, target), 75.0, sensor_fit='HORIZONTAL')
    return finish(scene, cam, (0.25, 0.1, -0.03), (-0.5, 0.0, -4.0), "corpus_glossy.blend")


def build_courtyard():
    scene = corpus_scene("CorpusCourtyard")
    set_world(scene, "BlueSky", (0.42, 0.62, 1.0), 1.0)
    ground = diffuse_material("Paving", (0.45, 0.43, 0.4))
    plaster = diffuse_material("Plaster", (0.78, 0.72, 0.62))
    ochre = diffuse_material("Ochre", (0.75, 0.5, 0.22))
    stone = diffuse_material("Stone", (0.6, 0.6, 0.58))
    crate = diffuse_material("Crate", (0.5, 0.34, 0.2))
    x, y, h = (-7.0, 7.0), (-7.0, 7.0), 4.0
    room_shell(x, y, (0.0, h), {"floor": ground, "walls": plaster, "BackWall": ochre},
               skip=("Ceiling",))
    # Arcade along the back wall: a roof slab on a row of pillars.
    add_box("ArcadeRoof", (14.0, 3.2, 0.25), (0.0, 5.4, 3.0), stone)
    pillars = merge(*[box_geometry((0.35, 0.35, 2.875), (px, 0.0, 1.4375))
                      for px in np.arange(-6.0, 6.01, 2.0)])
    add_mesh("ArcadePillars", pillars[0], pillars[1], stone, location=(0.0, 4.0, 0.0))
    add_box("Pillar1", (0.5, 0.5, 3.0), (-1.5, 0.5, 1.5), stone)
    add_box("Pillar2", (0.5, 0.5, 3.0), (2.5, -1.0, 1.5), stone)
    add_box("Crate1", (1.0, 1.0, 1.0), (-3.0, -1.5, 0.5), crate, rot_z_deg=15.0)
    add_box("Crate2", (0.8, 0.8, 0.8), (-2.6, -0.3, 0.4), crate, rot_z_deg=-20.0)
    add_box("Crate3", (1.2, 0.9, 0.7), (1.0, 2.0, 0.35), crate, rot_z_deg=5.0)
    add_box("Bench", (2.0, 0.5, 0.45), (4.0, 1.5, 0.225), stone, rot_z_deg=90.0)
    d = sun_direction(42.0, -60.0)
    add_light("Sun", "SUN", 3.0, (0.0, 0.0, 10.0), d, color=(1.0, 0.93, 0.82),
              angle=np.radians(1.0))
    eye, target = (-5.5, -6.0, 1.7), (1.5, 4.5, 1.6)
    cam = add_camera("Camera", eye, look_at_rotation(eye, target), 80.0, sensor_fit='HORIZONTAL')
    return finish(scene, cam, (0.3, 0.2, 0.0), (0.0, 0.0, -3.0), "corpus_courtyard.blend")


def build_emitters():
    scene = corpus_scene("CorpusEmitters")
    set_world(scene, "Black", (0.0, 0.0, 0.0), 1.0)
    walls = diffuse_material("WallWhite", (0.75, 0.75, 0.75))
    floor = diffuse_material("FloorGrey", (0.5, 0.5, 0.5))
    wood = diffuse_material("Wood", (0.5, 0.34, 0.2))
    x, y, z = (-3.0, 3.0), (-2.5, 2.5), (0.0, 3.0)
    room_shell(x, y, z, {"floor": floor, "ceiling": walls, "walls": walls})
    add_box("Table", (1.6, 0.9, 0.75), (0.3, 0.6, 0.375), wood, rot_z_deg=10.0)
    add_box("Shelf", (0.5, 1.8, 1.9), (2.7, -0.6, 0.95), wood)
    add_box("Cube", (0.6, 0.6, 0.6), (-1.6, 1.4, 0.3), walls, rot_z_deg=30.0)
    palette = [(1.0, 0.85, 0.6), (1.0, 0.2, 0.1), (0.2, 1.0, 0.3), (0.2, 0.4, 1.0),
               (1.0, 0.55, 0.1), (0.2, 0.9, 1.0), (1.0, 0.25, 0.9), (1.0, 1.0, 1.0)]
    mats = [emission_material(f"Glow{i}", c, 12.0) for i, c in enumerate(palette)]
    rng = np.random.default_rng(7)
    spots = []
    for i in range(8):      # along the back and side walls, at various heights
        spots.append((-2.6 + 0.7 * i, 2.4, rng.uniform(0.6, 2.5)))
    for i in range(6):
        spots.append((-2.9, -2.0 + 0.75 * i, rng.uniform(0.5, 2.6)))
        spots.append((2.9, -2.2 + 0.4 * i, rng.uniform(2.0, 2.7)))
    for i in range(6):      # hanging under the ceiling
        spots.append((rng.uniform(-2.4, 2.4), rng.uniform(-1.8, 2.0), 2.6))
    for i in range(3):      # on the table
        spots.append((0.0 + 0.3 * i, 0.6, 0.81))
    for i in range(3):      # on the floor
        spots.append((rng.uniform(-2.5, -0.5), rng.uniform(-2.0, 0.0), 0.06))
    for i, p in enumerate(spots):
        add_box(f"Emitter{i:02d}", (0.12, 0.12, 0.12), p, mats[i % len(mats)],
                rot_z_deg=float(rng.uniform(0, 90)))
    eye, target = (-2.3, -2.1, 1.5), (0.8, 1.3, 1.0)
    cam = add_camera("Camera", eye, look_at_rotation(eye, target), 78.0, sensor_fit='HORIZONTAL')
    return finish(scene, cam, (0.2, 0.2, 0.0), (0.0, 0.0, 4.0), "corpus_emitters.blend")


BUILDERS = {"room": build_room, "movers": build_movers, "slit": build_slit, "glossy": build_glossy,
            "courtyard": build_courtyard, "emitters": build_emitters}


def main(names):
    for name in names or BUILDERS:
        BUILDERS[name]()


if __name__ == "__main__":
    main(sys.argv[1:])
