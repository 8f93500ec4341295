"""Helpers for the node graph tests: materials and node groups built with the
node_tree API, and checks every translated graph must pass."""

import importlib

import pytest


def modules(addon):
    """(node_graph, node_values, core.materials.shader.graph) as the registered add-on has them."""
    return tuple(importlib.import_module(f"{addon.__name__}.{name}") for name in (
        "restir_addon.export.node_graph", "restir_addon.export.node_values", "core.materials.shader.graph"))


def new_material(name):
    """A fresh material: (material, tree, its Principled BSDF, its Material Output)."""
    import bpy
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    return mat, tree, tree.nodes["Principled BSDF"], tree.nodes["Material Output"]


def graph_of(ng, mat, images=None):
    """The material's graph, checked for evaluation order."""
    graph = ng.material_graph(mat, images)
    assert_topological(graph)
    return graph


def assert_topological(graph):
    """Every link points to an earlier node."""
    for i, node in enumerate(graph.nodes):
        for value in node.inputs.values():
            if hasattr(value, "node"):
                assert 0 <= value.node < i, (node.name, value)
    if graph.output is not None:
        assert 0 <= graph.output.node < len(graph.nodes)


def kinds(graph):
    return [n.kind for n in graph.nodes]


def find(graph, name):
    """(index, node) of the graph node called name."""
    hits = [(i, n) for i, n in enumerate(graph.nodes) if n.name == name]
    assert len(hits) == 1, (name, [n.name for n in graph.nodes])
    return hits[0]


def approx(value):
    return pytest.approx(value, abs=1e-6)


def new_group(name, inputs=(), outputs=()):
    """A shader node group with the given (name, socket type) interface and its
    Group Input and Group Output nodes."""
    import bpy
    group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    for socket_name, socket_type in inputs:
        group.interface.new_socket(socket_name, in_out="INPUT", socket_type=socket_type)
    for socket_name, socket_type in outputs:
        group.interface.new_socket(socket_name, in_out="OUTPUT", socket_type=socket_type)
    return group, group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")


def group_node(tree, group, name):
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.name = name
    return node
