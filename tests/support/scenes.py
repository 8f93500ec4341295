"""Small scenes built in code for the core tests (no Blender), and every
path's colour of one (path_samples)."""

import dataclasses

import numpy as np

from restir_gi.core import Camera, Lights, Materials, RenderContext, make_scene
from restir_gi.core.camera.projection import PixelFilter
from restir_gi.core.integrators.path import camera_pass
from restir_gi.core.scene import LIGHT_AREA, LIGHT_POINT


def look_at(eye, target, up=(0, 0, 1)):
    """Blender-style camera matrix: the camera looks down its local -Z."""
    eye, target, up = (np.asarray(a, np.float64) for a in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    upv = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, upv, back, eye
    return m.astype(np.float32)


def quad(p0, e1, e2):
    """Vertices and two triangles of the parallelogram p0, p0 + e1, p0 + e1 + e2, p0 + e2."""
    p0, e1, e2 = (np.asarray(a, np.float32) for a in (p0, e1, e2))
    v = np.stack([p0, p0 + e1, p0 + e1 + e2, p0 + e2])
    return v, np.array([[0, 1, 2], [0, 2, 3]], np.int32)


class Builder:
    def __init__(self):
        self.v, self.t, self.m = [], [], []
        self.count = 0

    def add(self, verts, tris, material):
        self.v.append(verts)
        self.t.append(tris + self.count)
        self.m.append(np.full(len(tris), material, np.int32))
        self.count += len(verts)

    def add_box(self, lo, hi, material):
        lo, hi = np.asarray(lo, np.float32), np.asarray(hi, np.float32)
        dx, dy, dz = hi - lo
        ex, ey, ez = np.float32([dx, 0, 0]), np.float32([0, dy, 0]), np.float32([0, 0, dz])
        for p0, a, b in ((lo, ey, ex), (lo + ez, ex, ey), (lo, ex, ez), (lo + ey, ez, ex),
                         (lo, ez, ey), (lo + ex, ey, ez)):
            self.add(*quad(p0, a, b), material)

    def arrays(self):
        return np.concatenate(self.v), np.concatenate(self.t), np.concatenate(self.m)


def cornell_box(light="emitter", width=64, height=64, emission=15.0, power=100.0, radius=0.05):
    """The Cornell box of the example blends: x, y in [-1, 1], z in [0, 2], open
    toward the camera at -y. light: 'emitter' (quad), 'point' (of ``radius``)
    or 'area'."""
    mats = [
        {"name": "white", "base_color": (0.8, 0.8, 0.8)},
        {"name": "red", "base_color": (0.8, 0.1, 0.1)},
        {"name": "green", "base_color": (0.1, 0.8, 0.1)},
        {"name": "light", "base_color": (0, 0, 0), "emission": (emission,) * 3},
    ]
    b = Builder()
    b.add(*quad((-1, -1, 0), (2, 0, 0), (0, 2, 0)), 0)       # floor
    b.add(*quad((-1, -1, 2), (0, 2, 0), (2, 0, 0)), 0)       # ceiling
    b.add(*quad((-1, 1, 0), (2, 0, 0), (0, 0, 2)), 0)        # back
    b.add(*quad((-1, -1, 0), (0, 2, 0), (0, 0, 2)), 1)       # left, red
    b.add(*quad((1, -1, 0), (0, 0, 2), (0, 2, 0)), 2)        # right, green
    b.add_box((-0.6, -0.1, 0), (-0.05, 0.5, 1.2), 0)         # tall box
    b.add_box((0.1, -0.6, 0), (0.65, -0.05, 0.6), 0)         # short box
    lights = Lights.empty()
    if light == "emitter":
        b.add(*quad((-0.25, -0.25, 1.98), (0.5, 0, 0), (0, 0.5, 0)), 3)
    elif light == "point":
        lights = Lights.from_list([{"kind": LIGHT_POINT, "position": (0, 0, 1.8), "power": (power,) * 3,
                                    "radius": radius}])
    elif light == "area":
        lights = Lights.from_list([{"kind": LIGHT_AREA, "position": (0, 0, 1.98), "direction": (0, 0, -1),
                                    "power": (power,) * 3, "size_u": 0.5, "size_v": 0.5}])
    v, t, m = b.arrays()
    cam = Camera(to_world=look_at((0, -3.9, 1), (0, 0, 1)), lens=50.0, sensor_width=36.0)
    return make_scene(v, t, m, Materials.from_list(mats), lights, cam, width=width, height=height)


def furnace(albedo=0.5, world=1.0, width=16, height=16):
    """A closed-form case: a diffuse sphere-ish box under a uniform white world.
    A convex object under a constant world of radiance Lw with albedo a has
    outgoing radiance a * Lw after one bounce... use a single plane instead:
    a large diffuse plane seen from above under world Lw reflects exactly a * Lw
    (no occlusion, no interreflection)."""
    b = Builder()
    b.add(*quad((-50, -50, 0), (100, 0, 0), (0, 100, 0)), 0)
    v, t, m = b.arrays()
    mats = Materials.from_list([{"base_color": (albedo,) * 3}])
    cam = Camera(to_world=look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0)), lens=50.0)
    return make_scene(v, t, m, mats, Lights.empty(), cam, world_color=(world,) * 3,
                      width=width, height=height)


def tilted_emitter(width=20, height=20):
    """A bright square at an angle in front of a grey backdrop under a dim
    world: its outline crosses pixels at every slope (anti-aliasing tests)."""
    b = Builder()
    b.add(*quad((-1.0, 1.0, -0.6), (1.6, 0, 0), (0, 0, 1.6)), 0)
    b.add(*quad((-0.45, 0.0, -0.1), (0.6, 0, 0.25), (-0.2, 0, 0.55)), 1)
    mats = Materials.from_list([{"base_color": (0.5, 0.5, 0.5)},
                                {"base_color": (0, 0, 0), "emission": (8.0, 8.0, 8.0)}])
    cam = Camera(to_world=look_at((0, -4, 0), (0, 0, 0)), lens=50.0, sensor_width=36.0)
    return make_scene(*b.arrays(), mats, Lights.empty(), cam, world_color=(0.2, 0.2, 0.2),
                      width=width, height=height)


def open_yard(width=32, height=32):
    """Ground, a wall and two blocks under a bright constant sky (no lights):
    open surfaces whose indirect light is mostly sky found by BSDF samples,
    partly hidden near the wall and the blocks."""
    b = Builder()
    b.add(*quad((-6, -6, 0), (12, 0, 0), (0, 12, 0)), 0)
    b.add_box((-6, 3, 0), (6, 3.5, 3), 1)
    b.add_box((-2, -1, 0), (-0.8, 0.2, 1.5), 1)
    b.add_box((1, 0.5, 0), (2.5, 1.5, 0.8), 0)
    mats = Materials.from_list([{"base_color": (0.45, 0.43, 0.4)}, {"base_color": (0.78, 0.72, 0.62)}])
    cam = Camera(to_world=look_at((-1, -7, 3.5), (0.5, 1.5, 0.5)), lens=35.0, sensor_width=36.0)
    return make_scene(*b.arrays(), mats, Lights.empty(), cam, world_color=(0.42, 0.62, 1.0),
                      width=width, height=height)


def glow_by_wall(width=24, height=24):
    """A small emissive cube 4 cm in front of a grey wall, seen straight on:
    the wall around it is lit from closer than the cube is wide."""
    b = Builder()
    b.add(*quad((-1, 0.5, -1), (2, 0, 0), (0, 0, 2)), 0)
    b.add_box((-0.06, 0.34, -0.06), (0.06, 0.46, 0.06), 1)
    mats = Materials.from_list([{"base_color": (0.6, 0.6, 0.6)},
                                {"base_color": (0, 0, 0), "emission": (12.0, 10.0, 8.0)}])
    cam = Camera(to_world=look_at((0.3, -1.2, 0.2), (0, 0.5, 0)), lens=50.0, sensor_width=36.0)
    return make_scene(*b.arrays(), mats, Lights.empty(), cam, width=width, height=height)


def path_samples(scene, samples, max_bounces, seed=0):
    """Every path's colour, (samples * pixels, 3) float64, from camera_pass."""
    ctx = RenderContext.build(scene)
    pf = PixelFilter(scene.filter_width)
    try:
        out = [camera_pass(ctx, scene.width, scene.height, seed, 0, s, max_bounces, pf).color
               for s in range(samples)]
    finally:
        ctx.close()
    return np.concatenate(out).astype(np.float64)


EYE, TARGET = np.array([0.0, -2.8, 1.0]), np.array([0.0, 0.0, 1.0])


def sharp(scene):
    """Pixel centres only (no filter jitter), so frames are comparable pixel by pixel."""
    scene.filter_width = 0.0
    return scene


def inside_box(width, height):
    """The Cornell box seen from close to its open side: walls fill the image."""
    scene = sharp(cornell_box("area", width, height))
    scene.camera = dataclasses.replace(scene.camera, to_world=look_at(EYE, TARGET))
    return scene


def closed_box(albedo, emission, size=12):
    """The inside of a box whose six walls all have the same Lambert albedo and
    emission, seen from a camera inside it."""
    b = Builder()
    b.add_box((-1, -1.5, -0.8), (1.2, 1, 1), 0)
    v, t, m = b.arrays()
    mats = Materials.from_list([{"base_color": albedo, "emission": emission}])
    cam = Camera(to_world=look_at((0.1, -0.3, 0.2), (0.6, 1.0, -0.5)), lens=18.0)
    return make_scene(v, t, m, mats, Lights.empty(), cam, width=size, height=size)
