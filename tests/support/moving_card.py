"""A floor lit by a point light and a card that slides over it: the scenes of
the moving-object tests (tests/core/restir/test_restir_moving_objects.py,
test_gradients.py)."""

import numpy as np

from restir_gi.core import Camera, Lights, Materials, make_scene
from restir_gi.core.scene import LIGHT_POINT
from support.scenes import Builder, look_at, quad

SIZE = 64


def scene_with(card_verts, x, patch=False, power=None):
    """A floor (object 0) lit by a point light above the origin (or with
    ``patch``, by one just above the floor, which lights a small patch of
    it; ``power`` in place of its own), and a card (object 1, quad corners
    card_verts) translated by x along the x axis."""
    b = Builder()
    b.add(*quad((-4, -4, 0), (8, 0, 0), (0, 8, 0)), 0)
    p0, e1, e2 = card_verts
    b.add(*quad(np.add(p0, (x, 0, 0)), e1, e2), 1)
    light = ((0, -1.0, 0.4), 60.0) if patch else ((0, 0, 3.0), 400.0)
    light = (light[0], light[1] if power is None else power)
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": light[0], "power": (light[1],) * 3}])
    cam = Camera(to_world=look_at((0, -4, 3), (0, 0, 0.3)), lens=35.0, sensor_width=36.0)
    mats = Materials.from_list([{"base_color": (0.8, 0.8, 0.8)}, {"base_color": (0.8, 0.6, 0.3)}])
    scene = make_scene(*b.arrays(), mats, lights, cam, object_ids=np.array([0, 0, 1, 1]),
                       width=SIZE, height=SIZE)
    card = np.eye(4)
    card[0, 3] = x
    scene.object_keys = ["floor", "card"]
    scene.object_matrices = np.stack([np.eye(4), card])
    return scene


# A horizontal card half way up to the light: its shadow on the floor is
# twice its size and moves twice as fast.
OCCLUDER = ((-0.4, -0.4, 1.5), (0.8, 0, 0), (0, 0.8, 0))
# A card standing on the floor, facing the camera, lit by the floor in front of it.
STANDING = ((-0.6, -0.6, 0.0), (1.2, 0, 0), (0, 0, 1.0))
