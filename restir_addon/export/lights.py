"""Blender light objects to core light rows (Cycles' units are kept as they are)."""

import numpy as np

from ...core.shader.nodes_spectrum import blackbody_rec709
from .node_graph import translate
from .node_values import uses_nodes

from ...core.scene import (LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, SHAPE_DISK,
                           SHAPE_ELLIPSE, SHAPE_RECTANGLE, SHAPE_SQUARE)

_KIND = {"POINT": LIGHT_POINT, "SPOT": LIGHT_SPOT, "SUN": LIGHT_SUN, "AREA": LIGHT_AREA}
_SHAPE = {"SQUARE": SHAPE_SQUARE, "RECTANGLE": SHAPE_RECTANGLE, "DISK": SHAPE_DISK,
          "ELLIPSE": SHAPE_ELLIPSE}


def light_row(light_object, matrix, warn):
    """A dict for core.Lights.from_list from a light object and its world matrix."""
    light = light_object.data
    name = light_object.name
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
        "power": color * float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0)),
    }
    row["camera_visible"] = bool(getattr(light_object, "visible_camera", False))
    row["hidden_kinds"] = tuple(not bool(getattr(light_object, "visible_" + k, True))
                                for k in ("diffuse", "glossy", "transmission"))
    if light.type in ("POINT", "SPOT"):
        row["radius"] = float(light.shadow_soft_size)
        row["soft_falloff"] = bool(getattr(light, "use_soft_falloff", True))
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
        if not row["size_u"] * row["size_v"] > 0:
            # As Cycles: an area light without area emits nothing.
            warn(f"Light '{name}': area light of zero size emits no light")
            row["power"] = np.zeros(3)
        spread = float(getattr(light, "spread", np.pi))
        if spread < np.pi - 1e-4:
            warn(f"Light '{name}': area light spread below 180 degrees is not supported")
    row["shadowless"] = not bool(getattr(light, "use_shadow", True))
    if float(light.energy) < 0:
        # Cycles subtracts the light of a negative power; it is left out here.
        warn(f"Light '{name}': negative power is not supported; the light emits nothing")
        row["power"] = np.zeros(3)
    if getattr(light, "use_temperature", False):
        row["power"] = row["power"] * blackbody_rec709(np.float32(light.temperature)).ravel()
    if uses_nodes(light):
        row["power"] = row["power"] * _node_emission(light, warn)
    if not getattr(light, "normalize", True):
        row["power"] = row["power"] * _unnormalized_factor(row)
    return row


def _node_emission(light, warn):
    """The colour x strength a light's node tree emits (Cycles multiplies the
    light's power by it): its Emission node, evaluated once. Textures in a
    light's nodes vary over the light, which is not modelled: a warning, and
    the value they give at the light's centre."""
    from ...core.shader import CompiledShader, WorldGeometry   # noqa: PLC0415
    plain = _plain_emission(light.node_tree)
    if plain is not None:
        return plain
    graph = translate(light.node_tree, ("OUTPUT_LIGHT",), None, light.name)
    if graph.output is None:
        return np.ones(3)
    shader = CompiledShader(graph, {}, lambda text: warn(f"Light '{light.name}': {text}"))
    if not shader.uniform:
        warn(f"Light '{light.name}': textures in its nodes are not supported; using their value "
             f"at one point")
    closure = shader.closure(WorldGeometry(np.float32([[0.0, 0.0, 1.0]])))
    return np.asarray(closure.get("emission", 1)[0], np.float64)


def _plain_emission(tree):
    """Colour x strength of a tree that is one Emission node feeding the Light
    Output and nothing else, read off its sockets; None for any other tree.
    Every light has that tree from Blender 5.2 on, where it always renders:
    this spares each light a graph compilation (0.2 ms)."""
    nodes, links = tree.nodes, tree.links
    if len(nodes) != 2 or len(links) != 1:
        return None
    link = links[0]
    emit, out = link.from_node, link.to_node
    if (emit.type != "EMISSION" or out.type != "OUTPUT_LIGHT" or emit.mute or link.is_muted
            or not link.is_valid or link.from_socket != emit.outputs[0]
            or link.to_socket != out.inputs[0] or any(i.is_linked for i in emit.inputs)):
        return None
    color = emit.inputs["Color"].default_value
    return np.array(color[:3], np.float64) * float(emit.inputs["Strength"].default_value)


def _unnormalized_factor(row):
    """Power scale that turns Blender's 'normalize off' convention (radiance =
    power / pi, independent of size) into the normalised formulas core uses."""
    kind = row["kind"]
    if kind in (LIGHT_POINT, LIGHT_SPOT):
        r = row.get("radius", 0.0)
        return 4.0 * np.pi * r * r if r > 0 else 4.0
    if kind == LIGHT_SUN:
        half = 0.5 * row.get("angle", 0.0)
        return np.pi * np.sin(half) ** 2 if half > 0 else 1.0
    area = row["size_u"] * row["size_v"] * (np.pi / 4 if row["shape"] in (SHAPE_DISK, SHAPE_ELLIPSE) else 1.0)
    return area


def is_supported(light):
    return light.type in _KIND


def row_signature(row):
    """A comparable form of a light row (dict of plain values and arrays)."""
    return tuple(sorted((k, tuple(np.ravel(v).tolist()) if not isinstance(v, str) else v)
                        for k, v in row.items()))
