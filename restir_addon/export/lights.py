"""Blender light objects to core light rows (Cycles' units are kept as they are)."""

import numpy as np

from ...core.scene import (LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_DISK,
                           SHAPE_ELLIPSE, SHAPE_RECTANGLE, SHAPE_SQUARE)

_KIND = {"POINT": LIGHT_POINT, "SPOT": LIGHT_SPOT, "SUN": LIGHT_SUN, "AREA": LIGHT_AREA}
_SHAPE = {"SQUARE": SHAPE_SQUARE, "RECTANGLE": SHAPE_RECTANGLE, "DISK": SHAPE_DISK,
          "ELLIPSE": SHAPE_ELLIPSE}


def light_row(light, matrix, name):
    """A dict for core.Lights.from_list from a bpy Light and its world matrix."""
    m = np.asarray(matrix, np.float64)
    axes = m[:3, :3]
    scale = np.linalg.norm(axes, axis=0)
    unit = axes / np.where(scale > 0, scale, 1)
    color = np.asarray(light.color, np.float64)
    row = {
        "name": name,
        "kind": _KIND[light.type],
        "position": m[:3, 3],
        "direction": -unit[:, 2],
        "axis_u": unit[:, 0],
        "axis_v": unit[:, 1],
        "power": color * float(light.energy),
    }
    if light.type in ("POINT", "SPOT"):
        row["radius"] = float(light.shadow_soft_size)
    if light.type == "SPOT":
        row["spot_size"] = float(light.spot_size)
        row["spot_blend"] = float(light.spot_blend)
    elif light.type == "SUN":
        row["angle"] = float(light.angle)
    elif light.type == "AREA":
        shape = _SHAPE.get(light.shape, SHAPE_SQUARE)
        size_u = float(light.size)
        size_v = float(light.size_y) if shape in (SHAPE_RECTANGLE, SHAPE_ELLIPSE) else size_u
        row["shape"] = shape
        row["size_u"] = size_u * scale[0]
        row["size_v"] = size_v * scale[1]
    return row


def is_supported(light):
    return light.type in _KIND
