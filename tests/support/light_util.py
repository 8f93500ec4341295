"""Shared pieces of the light tests (tests/core/lights/): constants, a
LightSet over analytic lights and emissive triangles, the NEE estimate and
its check against a reference, an area light's row."""

import numpy as np

from restir_gi.core import Lights, Materials, make_scene
from restir_gi.core.lights.light_set import LightSet
from restir_gi.core.scene import LIGHT_AREA

N = 200_000
COLOR = np.array([1.0, 0.5, 0.25])
ORIGIN = np.zeros(3)
UP = np.array([0.0, 0.0, 1.0])


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


TILTED = unit([0.4, -0.3, 1.0])


def light_set(rows, tri_verts=None, emission=(0, 0, 0), two_sided=True):
    """A LightSet over analytic lights and, optionally, emissive triangles."""
    lights = Lights.from_list(rows)
    if tri_verts is None:
        scene = make_scene(np.zeros((0, 3)), np.zeros((0, 3)), lights=lights)
    else:
        v = np.asarray(tri_verts, np.float32).reshape(-1, 3)
        t = np.arange(len(v), dtype=np.int32).reshape(-1, 3)
        mats = Materials.from_list([{"base_color": (0, 0, 0), "emission": emission}])
        scene = make_scene(v, t, materials=mats, lights=lights)
    return scene, LightSet(scene, emission_two_sided=two_sided)


def nee(ls, p, n, rng, count=N):
    """Mean and standard error (3,) of radiance * cos / pdf over light samples."""
    P = np.ascontiguousarray(np.broadcast_to(np.float32(p), (count, 3)))
    s = ls.sample(P, rng.random(count, dtype=np.float32), rng.random((count, 2), dtype=np.float32))
    cos = np.maximum(s.wi.astype(np.float64) @ n, 0.0)
    val = np.where((s.pdf > 0)[:, None], s.radiance * (cos / np.where(s.pdf > 0, s.pdf, 1))[:, None], 0.0)
    return val.mean(axis=0), val.std(axis=0) / np.sqrt(count), s


def assert_close(est, err, ref, rel=2e-4, max_rel_err=0.01):
    ref = np.asarray(ref, np.float64)
    assert (err <= max_rel_err * np.abs(ref).max() + 1e-12).all(), "too noisy to tell anything"
    assert (np.abs(est - ref) <= 4.5 * err + rel * np.abs(ref) + 1e-9).all(), (est, ref, err)


def area_row(shape, su, sv, centre, au, av, power):
    au, av = unit(au), unit(av)
    return {"kind": LIGHT_AREA, "position": centre, "direction": np.cross(au, av), "axis_u": au,
            "axis_v": av, "power": power, "shape": shape, "size_u": su, "size_v": sv}


# An emissive triangle above the origin.
TRIANGLE = np.array([[-0.5, -0.4, 1.3], [0.7, -0.2, 1.1], [0.1, 0.6, 1.6]])
