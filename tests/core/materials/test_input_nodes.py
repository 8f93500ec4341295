"""Input nodes (core/materials/shader/nodes_input.py) that the shader-graph
tests do not reach: what the Ambient Occlusion node gives without rays (the
Attribute node without a name is in tests/oracle's node families)."""

import numpy as np

from restir_gi.core.materials.shader import CompiledShader, Link, Node, ShaderGraph, WorldGeometry

ONE = WorldGeometry(np.array([[0.0, 0.0, 1.0]], np.float32))


def outputs(nodes, warn=None):
    return CompiledShader(ShaderGraph(nodes=nodes, output=None), warn=warn).outputs(ONE)


def test01_ambient_occlusion_passes_its_colour_and_says_so():
    """The node traces no rays: its Color output is its Color input (a
    linked one too), AO is 1, and the material's warning names the node
    once, however many there are."""
    warnings = []
    out = outputs([Node("RGB", {}, {"color": (0.2, 0.3, 0.4)}, "rgb"),
                   Node("AMBIENT_OCCLUSION", {"Color": Link(0, "Color", "RGBA", "RGBA"), "Distance": 1.0}, {}, "AO"),
                   Node("AMBIENT_OCCLUSION", {"Color": (0.5, 0.6, 0.7)}, {}, "AO 2")], warnings.append)
    np.testing.assert_allclose(np.asarray(out[1]["Color"]).reshape(-1, 3)[0], [0.2, 0.3, 0.4], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(out[2]["Color"]).reshape(-1, 3)[0], [0.5, 0.6, 0.7], rtol=1e-6)
    assert float(out[1]["AO"]) == 1.0
    assert len(warnings) == 1 and "AMBIENT_OCCLUSION" in warnings[0] and "not traced" in warnings[0]
