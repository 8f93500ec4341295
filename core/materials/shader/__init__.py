"""Shader node graphs: plain data from the exporter (graph.py), run over
batches of hits (evaluate.py) by one evaluator per node type (nodes_*.py),
leaving closures (closure.py) that core/materials/shading.py turns into BSDF
parameters."""

from . import (  # noqa: F401 (registers)
    nodes_color, nodes_hair, nodes_input, nodes_math, nodes_noise, nodes_shader, nodes_spectrum,
    nodes_texture, nodes_voronoi)
from .closure import Closure
from .evaluate import EVALUATORS, CompiledShader
from .geometry import SurfaceGeometry, WorldGeometry
from .graph import Link, Node, ShaderGraph

__all__ = ["Closure", "CompiledShader", "EVALUATORS", "Link", "Node", "ShaderGraph",
           "SurfaceGeometry", "WorldGeometry"]
