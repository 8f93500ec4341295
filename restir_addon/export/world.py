"""The world: its node graph (node_graph.py) as a core Environment light,
and its Volume output as the medium filling the scene."""

from ...core.lights.world import world_environment
from .node_graph import world_graph


def evaluated_world(depsgraph):
    """The scene's world as the depsgraph evaluated it: its animated values
    (a keyframed strength, a rotating HDRI's mapping) at this frame. The
    original datablock keeps the values of the frame the render began on."""
    world = depsgraph.scene.world
    return world.evaluated_get(depsgraph) if world is not None else None


def export_world(world, images, warn):
    """(signature, build): the world graph's text, to tell whether it changed,
    and a function building (its Environment, its volume): the Environment
    None for a black world (building an importance map evaluates the graph
    over the whole sphere, so the viewport builds it only when the signature
    changed), the volume a medium dict (Scene.world_volume) or None."""
    graph = world_graph(world, images)
    name = world.name if world is not None else ""
    for text in graph.warnings:
        warn(f"World '{name}': {text}")
    graph.warnings = []
    signature = repr(graph)

    def build():
        environment = world_environment(graph, images.images, lambda text: warn(f"World '{name}': {text}"))
        return environment, graph.volume

    return signature, build
