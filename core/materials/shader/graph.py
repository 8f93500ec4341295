"""Shader graphs as plain data.

The add-on's exporter turns a Blender node tree into a ShaderGraph: node
groups and reroutes flattened, muted nodes passed through, nodes listed in
evaluation order (every link points to an earlier node). core/materials/shader/evaluate.py
runs a graph over a batch of hits. Nothing here knows about bpy, but the
vocabulary is Blender's: ``Node.kind`` is the node's ``type`` (``MATH``,
``TEX_IMAGE``, ``BSDF_PRINCIPLED``, ...), input keys are the sockets'
``identifier`` (``Value_001``, ``A_Color``, ``Base Color``), and ``props`` hold
the node's own settings (``operation``, ``blend_type``, ...) as plain values.

Socket values are floats, 3-tuples (vectors and colours, alpha dropped) or
Links. A link between sockets of different types carries the conversion
Blender applies (``Link.convert``): colour to float by luminance, vector to
float by the mean of the components, float to colour or vector by repeating it.
"""

from dataclasses import dataclass, field

# Socket types, as Blender names them (NodeSocket.type).
FLOAT = "VALUE"
VECTOR = "VECTOR"
COLOR = "RGBA"
SHADER = "SHADER"
INT = "INT"
BOOL = "BOOLEAN"


@dataclass(frozen=True)
class Link:
    """The value of output ``socket`` (identifier) of node number ``node``."""
    node: int
    socket: str
    from_type: str = ""     # socket types, for the conversion ("" = same type)
    to_type: str = ""


@dataclass
class Node:
    kind: str                                   # Blender's node.type
    inputs: dict = field(default_factory=dict)  # identifier -> float | tuple | Link
    props: dict = field(default_factory=dict)   # node settings as plain values
    name: str = ""                              # for warnings


@dataclass
class ShaderGraph:
    """One material's (or the world's) nodes in evaluation order.

    ``output``: the link into the output node's Surface socket, or None when
    nothing is linked (black, as Cycles renders it). ``warnings``: what the
    exporter could not translate. ``needs``: the per-hit data the nodes read
    (``uv:<map>``, ``color:<attribute>``, ``tangent:<map>``, ``generated``),
    so the exporter writes only those."""
    nodes: list
    output: Link = None
    name: str = ""
    warnings: list = field(default_factory=list)
    needs: set = field(default_factory=set)
    # The homogeneous medium of the Volume socket (core/integrators/media.py:
    # sigma_a, sigma_s, emission, g), None without one.
    volume: dict = None
    # Where a texture drives that medium's density (core/integrators/
    # field_media.py): the Density input's nodes as a graph whose output is
    # the density, ``volume`` then per unit of it; None: constant.
    volume_field: "ShaderGraph" = None

    def add(self, node):
        self.nodes.append(node)
        return len(self.nodes) - 1
