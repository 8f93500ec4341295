"""Blender light objects to core light rows (Cycles' units are kept as they are)."""

import numpy as np

from ...core.materials.shader.nodes_spectrum import blackbody_rec709
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
        emission, row["falloff"], row["falloff_smooth"] = _node_emission(light, warn)
        row["power"] = row["power"] * emission
    if not getattr(light, "normalize", True):
        row["power"] = row["power"] * _unnormalized_factor(row)
    return row


def _node_emission(light, warn):
    """(colour x strength, falloff, smooth) of a light's node tree: Cycles
    multiplies the light's power by the emission its tree gives, evaluated
    once (Emission colour and strength, constant or from other nodes), and
    a Light Falloff in it as the light's falloff (``_falloff``). Textures in
    a light's nodes vary over the light, which is not modelled: a warning,
    and the value they give at the light's centre."""
    from ...core.materials.shader import CompiledShader, WorldGeometry   # noqa: PLC0415
    plain = _plain_emission(light.node_tree)
    if plain is not None:
        return plain, 0.0, 0.0
    graph = translate(light.node_tree, ("OUTPUT_LIGHT",), None, light.name)
    if graph.output is None:
        return np.ones(3), 0.0, 0.0
    shader = CompiledShader(graph, {}, lambda text: warn(f"Light '{light.name}': {text}"))
    if not shader.uniform:
        warn(f"Light '{light.name}': textures in its nodes are not supported; using their value "
             f"at one point")
    falloff = [n for n in graph.nodes if n.kind == "LIGHT_FALLOFF"]
    if not falloff:
        return _emission_at(shader, WorldGeometry, [1.0])[0], 0.0, 0.0
    if light.type == "SUN":     # Cycles: distant lights pass the node's Strength
        return _emission_at(shader, WorldGeometry, [_FAR])[0], 0.0, 0.0
    return _falloff(shader, WorldGeometry, falloff, lambda text: warn(f"Light '{light.name}': {text}"))


_FAR = float(np.finfo(np.float32).max)
# Distances at which a tree with Light Falloff is evaluated to find its law.
_PROBES = np.array([0.125, 0.5, 1.0, 2.0, 8.0, 32.0])


def _emission_at(shader, geometry, distances):
    """(len(distances), 3) emission of the light's tree, its ray length set
    to each distance."""
    d = np.asarray(distances, np.float32)
    geom = geometry(np.tile(np.float32([0.0, 0.0, 1.0]), (len(d), 1)))
    geom.ray_length = d
    return np.asarray(shader.closure(geom).get("emission", len(d)), np.float64)


def _falloff(shader, geometry, nodes, warn):
    """The tree's emission as c x d^k x (d^2 / (s + d^2) where s > 0): the
    law of Cycles' Light Falloff outputs (k = 0 Quadratic, 1 Linear, 2
    Constant; s its Smooth), found by evaluating the tree at several
    distances d and matching those laws, so the falloff may pass through
    other nodes that scale it (Math, a Mix of colours). (c, k, s); a tree
    that follows none of them (two falloffs added, a falloff through a
    non-linear node) gives its value at distance 1 and a warning."""
    emission = _emission_at(shader, geometry, _PROBES)
    at_one = emission[list(_PROBES).index(1.0)]
    if not np.any(emission):
        return at_one, 0.0, 0.0
    smooths = {0.0}
    for node in nodes:
        value = node.inputs.get("Smooth", 0.0)
        if isinstance(value, (int, float)) and value > 0:
            smooths.add(float(value))
    d2 = _PROBES * _PROBES
    for k in (0, 1, 2):
        for s in sorted(smooths):
            law = _PROBES ** k * (d2 / (s + d2) if s > 0 else 1.0)
            c = emission / law[:, None]
            if np.allclose(c, c[2], rtol=1e-3, atol=1e-6 * np.abs(c[2]).max()):
                return c[2], float(k), s
    warn("its Light Falloff is combined in a way not supported (only one of its outputs, scaled); "
         "the light emits as at distance 1 from everywhere")
    return at_one, 0.0, 0.0


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
