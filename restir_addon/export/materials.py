"""Blender materials to core material rows.

The node behind the Material Output's Surface socket decides: Principled BSDF,
Diffuse BSDF, Glossy BSDF and Emission are read; anything else renders as the
neutral material with one warning naming the node. Inputs driven by other nodes
(textures) fall back to the socket's own value, with a warning.
"""

import bpy
import numpy as np

def uses_nodes(datablock):
    """Node-based shading: always in Blender 5 (where use_nodes is deprecated),
    the datablock's own switch before."""
    return bpy.app.version >= (5, 0, 0) or datablock.use_nodes


NEUTRAL = {"name": "neutral", "base_color": (0.8, 0.8, 0.8), "roughness": 0.5, "specular": 0.5}


def _value(node, name, warn, default):
    sock = node.inputs.get(name)
    if sock is None:
        return default
    if sock.is_linked:
        warn(f"Input '{name}' of node '{node.name}' is driven by other nodes, which is not "
             f"supported; using its own value")
    v = sock.default_value
    try:
        return tuple(v)[:3]
    except TypeError:
        return float(v)


def _surface_node(tree):
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    active = [n for n in outputs if n.is_active_output and n.target in ("ALL", "CYCLES")]
    output = (active or [n for n in outputs if n.target in ("ALL", "CYCLES")] or outputs or [None])[0]
    if output is None or not output.inputs["Surface"].is_linked:
        return None
    node = output.inputs["Surface"].links[0].from_node
    while node.type == "REROUTE" and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    return node


def material_row(mat, warn):
    """A dict for core.Materials.from_list; warn(text) reports a problem once."""
    if mat is None:
        return dict(NEUTRAL)
    name = mat.name
    tree = mat.node_tree if uses_nodes(mat) else None
    if tree is None:
        return {"name": name, "base_color": tuple(mat.diffuse_color)[:3], "metallic": float(mat.metallic),
                "roughness": float(mat.roughness), "specular": 0.5}
    node = _surface_node(tree)
    if node is None:
        return {"name": name, "base_color": (0, 0, 0)}  # no surface: black, as in Cycles
    w = lambda text: warn(f"Material '{name}': {text}")  # noqa: E731
    kind = node.type
    if kind == "BSDF_PRINCIPLED":
        strength = _value(node, "Emission Strength", w, 0.0)
        emission = np.asarray(_value(node, "Emission Color", w, (0, 0, 0))) * strength
        return {"name": name,
                "base_color": _value(node, "Base Color", w, (0.8, 0.8, 0.8)),
                "metallic": _value(node, "Metallic", w, 0.0),
                "roughness": _value(node, "Roughness", w, 0.5),
                "ior": _value(node, "IOR", w, 1.5),
                "specular": _value(node, "Specular IOR Level", w, 0.5),
                "emission": tuple(emission)}
    if kind == "BSDF_DIFFUSE":
        return {"name": name, "base_color": _value(node, "Color", w, (0.8, 0.8, 0.8)),
                "roughness": 1.0, "specular": 0.0}
    if kind in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC"):
        return {"name": name, "base_color": _value(node, "Color", w, (0.8, 0.8, 0.8)),
                "metallic": 1.0, "roughness": _value(node, "Roughness", w, 0.5)}
    if kind == "EMISSION":
        color = np.asarray(_value(node, "Color", w, (1, 1, 1)))
        strength = _value(node, "Strength", w, 1.0)
        return {"name": name, "base_color": (0, 0, 0), "specular": 0.0,
                "emission": tuple(color * strength)}
    warn(f"Material '{name}': node '{node.bl_label or node.bl_idname}' is not supported; "
         f"rendering it as a neutral grey diffuse material")
    row = dict(NEUTRAL)
    row["name"] = name
    return row
