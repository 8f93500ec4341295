"""The world background as a constant radiance (colour x strength)."""

import numpy as np

from .materials import uses_nodes


def export_world(world, warn):
    if world is None:
        return np.zeros(3, np.float32)
    tree = world.node_tree if uses_nodes(world) else None
    if tree is None:
        return np.asarray(world.color, np.float32)[:3]
    output = next((n for n in tree.nodes if n.type == "OUTPUT_WORLD" and n.is_active_output), None)
    output = output or next((n for n in tree.nodes if n.type == "OUTPUT_WORLD"), None)
    if output is None or not output.inputs["Surface"].is_linked:
        return np.zeros(3, np.float32)
    node = output.inputs["Surface"].links[0].from_node
    if node.type != "BACKGROUND":
        warn(f"World node '{node.bl_idname}' is not supported; the world is black")
        return np.zeros(3, np.float32)
    color_in, strength_in = node.inputs["Color"], node.inputs["Strength"]
    if color_in.is_linked or strength_in.is_linked:
        warn("World background inputs driven by nodes (sky/environment textures) are not "
             "supported; using the socket values")
    color = np.asarray(color_in.default_value, np.float32)[:3]
    return (color * float(strength_in.default_value)).astype(np.float32)
