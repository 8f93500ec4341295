"""Next-event estimation among many emitters: choosing them by power alone,
by place (core/lights/light_grid.py without cones), by place and cone as the grid's
cell alone sees them (``LOCAL`` 0), and by place and cone with each point's
own share among its cell's top clusters (the engine's choice).

Two scenes built in code, each with its shading points:

- ``small emitters``: 24 point lamps and 16 glowing squares scattered through
  a 10 x 10 x 3 m room; points on the floor (normal up) and on walls.
- ``downlights``: 8 spots (60 degree cones) pointing down from 2 m and 4
  ceiling panels facing down, over a 10 m floor; points on the floor and on
  walls.

Printed per scene and choice: the mean over the points of the relative
variance of one NEE sample's irradiance estimate (variance / mean^2, lower is
better; shadows are not traced, so this is the choice's own noise), and the
time of ``LightSet.sample`` for 57,600 points (one 320x180 frame's worth),
median of 7.

    .venv/bin/python bench/light_selection.py
"""

import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from core.lights import light_grid
from core.lights.light_set import LightSet
from core import Materials
from core.scene import LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, Lights, make_scene

SAMPLES = 20_000
POINTS = 40


def small_emitters(rng):
    rows = [{"kind": LIGHT_POINT, "position": tuple(p), "power": tuple(rng.uniform(20, 200, 3)), "radius": 0.05}
            for p in rng.uniform((-5, -5, 0.3), (5, 5, 2.7), (24, 3))]
    v, t = [[-5, -5, 0], [5, -5, 0], [5, 5, 0]], [[0, 1, 2]]
    for x, y, z in rng.uniform((-5, -5, 0.2), (4.8, 4.8, 2.8), (16, 3)):
        b = len(v)
        v += [[x, y, z], [x + 0.2, y, z], [x, y + 0.2, z]]
        t.append([b, b + 1, b + 2])
    mats = Materials.from_list([{"base_color": (0.5, 0.5, 0.5)}, {"emission": (8, 6, 4)}])
    mids = np.r_[0, np.ones(16)].astype(np.int32)
    return make_scene(np.float32(v), np.int32(t), material_ids=mids, materials=mats,
                      lights=Lights.from_list(rows))


def downlights(rng):
    rows = [{"kind": LIGHT_SPOT, "position": (x, y, 2.0), "direction": (0, 0, -1), "power": (300, 280, 250),
             "radius": 0.05, "spot_size": np.radians(60), "spot_blend": 0.2}
            for x, y in rng.uniform(-4.5, 4.5, (8, 2))]
    rows += [{"kind": LIGHT_AREA, "position": (x, y, 2.9), "direction": (0, 0, -1), "axis_u": (1, 0, 0),
              "axis_v": (0, -1, 0), "power": (100, 100, 100), "size_u": 0.5, "size_v": 0.5}
             for x, y in rng.uniform(-4.5, 4.5, (4, 2))]
    v = np.float32([[-5, -5, 0], [5, -5, 0], [5, 5, 3], [-5, 5, 3]])
    return make_scene(v, np.int32([[0, 1, 2], [0, 2, 3]]), lights=Lights.from_list(rows))


def relative_variance(ls, points, normal, rng):
    out = []
    for p in points:
        P = np.repeat([p], SAMPLES, axis=0).astype(np.float32)
        N = np.repeat([normal], SAMPLES, axis=0).astype(np.float32)
        s = ls.sample(P, rng.random(SAMPLES, dtype=np.float32), rng.random((SAMPLES, 2), dtype=np.float32), N)
        cos = np.maximum(s.wi.astype(np.float64) @ normal, 0.0)
        e = np.where(s.pdf > 0, s.radiance.mean(axis=1) * cos / np.where(s.pdf > 0, s.pdf, 1.0), 0.0)
        if e.mean() > 0:
            out.append(e.var() / e.mean() ** 2)
    return float(np.mean(out))


def sample_ms(ls, rng):
    p = rng.uniform((-5, -5, 0), (5, 5, 3), (57_600, 3)).astype(np.float32)
    u1, u2 = rng.random(57_600, dtype=np.float32), rng.random((57_600, 2), dtype=np.float32)
    times = []
    for _ in range(7):
        t = time.perf_counter()
        ls.sample(p, u1, u2)
        times.append(time.perf_counter() - t)
    return 1000 * statistics.median(times)


def main():
    facing, local = light_grid._facing, light_grid.LOCAL
    choices = {
        "power alone": lambda ls: setattr(ls, "grid", None),
        "place": lambda ls: None,
        "place and cone, by cell": lambda ls: None,
        "place and cone": lambda ls: None,
    }
    print("| scene | choice | rel. variance, floor | rel. variance, walls | ms per 57,600 samples |")
    print("|---|---|---:|---:|---:|")
    for name, build in (("small emitters", small_emitters), ("downlights", downlights)):
        for choice, apply in choices.items():
            light_grid._facing = facing if choice.startswith("place and cone") else (lambda *a, **k: 1.0)
            light_grid.LOCAL = 0.0 if choice.endswith("by cell") else local
            rng = np.random.default_rng(1)
            ls = LightSet(build(rng))
            apply(ls)
            floor = np.c_[rng.uniform(-4.5, 4.5, (POINTS, 2)), np.zeros(POINTS)]
            walls = np.c_[rng.uniform(-4.5, 4.5, (POINTS, 2)), rng.uniform(0.2, 1.8, POINTS)]
            a = relative_variance(ls, floor, np.float64([0, 0, 1]), rng)
            b = relative_variance(ls, walls, np.float64([1, 0, 0]), rng)
            print(f"| {name} | {choice} | {a:.2f} | {b:.2f} | {sample_ms(ls, rng):.1f} |")
    light_grid._facing, light_grid.LOCAL = facing, local


if __name__ == "__main__":
    main()
