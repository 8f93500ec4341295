"""Blender shader node trees to plain shader graphs (core/materials/shader/graph.py).

Follows what Blender 5 does before Cycles sees a tree (it inlines the tree:
groups flattened, reroutes and muted nodes removed), so the graph means what
Cycles renders:

- Output: among the output nodes of the wanted types whose target is All or
  Cycles, one targeting Cycles beats one targeting All, then the active one
  wins. Outputs for EEVEE only are not Cycles' business: no output then.
- A value travels from the output socket of a real node to the socket reading
  it through reroutes, muted nodes (their internal links), group nodes (into
  the group's active Group Output) and Group Input nodes (out to whatever feeds
  the group node's socket). Muted links, invalid links (Blender's cycle
  breakers) and unavailable sockets count as absent.
- A linked value keeps its source socket's type: its Link converts once, from
  the source type to the reader's type, as Blender does (the types of the
  sockets it passed on the way do not matter). A constant (an unlinked
  socket's value reaching another socket through a group or a muted node) is
  converted at every socket it passes, as Blender does: a colour squeezed
  through a float group input comes out grey.
- Unlinked inputs hold their own value, except implicit inputs (a texture's
  Vector, Normal, Tangent): those are left out of ``Node.inputs`` and the
  evaluator supplies them (UV or generated coordinates, the shading normal).
  A constant reaching such a socket, or a shader socket, comes through a
  Value, Combine XYZ or RGB node linked to it, as Blender inserts them, so a
  constant in ``Node.inputs`` is always a real value.
- What cannot be resolved (a group without a tree or a Group Output, a group
  containing itself, a muted node's output without an internal link, a Group
  Input outside any group) is zero, Blender's fallback; all but the last two
  also leave a warning.
- Only the nodes the output depends on are listed, dependencies first, each
  (node, group path) once. Names are labels (else names) prefixed by the group
  path: ``"Group > Mix"``.

``images`` is anything with ``key(image) -> str`` (the image cache); without it
an image is known by its name.
"""

from collections import namedtuple

from ...core.materials.shader.graph import Link, Node, ShaderGraph

from .node_values import COLOR, FLOAT, SHADER, VECTOR, convert, node_props, plain, uses_nodes, zero
from .volumes import read_volume, textured_density

_GROUPS = ("GROUP", "CUSTOM GROUP")
_PROCEDURAL = frozenset(("TEX_BRICK", "TEX_CHECKER", "TEX_GABOR", "TEX_GRADIENT", "TEX_MAGIC",
                         "TEX_NOISE", "TEX_VORONOI", "TEX_WAVE", "TEX_WHITE_NOISE"))
# Vector sockets whose unlinked value Blender replaces by an implicit input.
_IMPLICIT = frozenset(("Normal", "Tangent", "Coat Normal", "Clear Coat Normal", "Position", "Direction"))

_Out = namedtuple("_Out", "index socket type")      # output `socket` of graph node `index`
_Const = namedtuple("_Const", "value type")          # a constant, of socket type `type`


def material_graph(material, images=None):
    """The graph behind a material's active Material Output's Surface.

    A material without a node tree renders, as in Cycles, as a Diffuse BSDF of
    its viewport colour. None gives an empty graph (no output)."""
    fallback = None if material is None else Node(
        "BSDF_DIFFUSE", {"Color": plain(material.diffuse_color, COLOR), "Roughness": 0.0}, name="Diffuse")
    graph = _graph_of(material, ("OUTPUT_MATERIAL",), fallback, "BSDF", images)
    for node in graph.nodes:        # Object Info > Material Index: the material's pass index
        if node.kind == "OBJECT_INFO":
            node.props["material_index"] = float(material.pass_index)
    return graph


def world_graph(world, images=None):
    """The graph behind a world's active World Output's Surface; a world without
    nodes is a Background of its colour. None gives an empty graph (black)."""
    fallback = None if world is None else Node(
        "BACKGROUND", {"Color": plain(world.color, COLOR), "Strength": 1.0}, name="Background")
    return _graph_of(world, ("OUTPUT_WORLD",), fallback, "Background", images)


def _graph_of(datablock, output_types, fallback, socket, images):
    """translate() of a datablock's tree, or the one-node ``fallback`` graph
    (output ``socket``) where it has no tree."""
    if datablock is None:
        return ShaderGraph(nodes=[])
    tree = datablock.node_tree if uses_nodes(datablock) else None
    if tree is None:
        graph = ShaderGraph(nodes=[], name=datablock.name)
        graph.output = Link(graph.add(fallback), socket)
        return graph
    return translate(tree, output_types, images, datablock.name)


def translate(tree, output_types=("OUTPUT_MATERIAL",), images=None, name=""):
    """The graph feeding the Surface socket of the tree's output node (see the
    module notes). Never raises: what fails is a warning."""
    graph = ShaderGraph(nodes=[], name=name)
    if tree is None:
        graph.warnings.append("no node tree")
        return graph
    try:
        output = _output_node(tree, output_types)
        if output is None:
            others = [n for n in tree.nodes if n.type in output_types]
            graph.warnings.append("only outputs for other render engines" if others else "no output node")
            return graph
        surface = output.inputs.get("Surface")
        if surface is not None and _available(surface):
            graph.output = _Translator(graph, images).reader_value(surface, _Scope(tree), output.name)
        volume = output.inputs.get("Volume")
        if volume is not None and volume.is_linked and _available(volume):
            # (A world's medium stays constant: its textured density warns.)
            density = textured_density(volume) if "OUTPUT_MATERIAL" in output_types else None
            graph.volume = read_volume(volume, graph.warnings.append, unit_density=density is not None)
            if density is not None and graph.volume is not None:
                field = ShaderGraph(nodes=[], name=f"{name} (volume density)")
                field.output = _Translator(field, images).reader_value(density, _Scope(tree), density.node.name)
                graph.warnings.extend(field.warnings)
                if isinstance(field.output, Link):
                    graph.volume_field = field
                else:       # the nodes give a constant: as a plain input
                    graph.volume = read_volume(volume, graph.warnings.append)
            if surface is not None and not surface.is_linked and "OUTPUT_MATERIAL" in output_types:
                # Cycles' boundary of a volume-only material (a smoke domain,
                # a fog box around the scene) lets light through: only the
                # medium inside it shows (core/integrators/media.py).
                graph.output = Link(graph.add(Node("BSDF_TRANSPARENT", {"Color": (1.0, 1.0, 1.0)},
                                                   name="Volume boundary")), "BSDF")
        displacement = output.inputs.get("Displacement")
        if displacement is not None and displacement.is_linked and _available(displacement):
            graph.warnings.append("displacement is not rendered")
    except RecursionError:
        graph.warnings.append("node tree too deep to translate")
        graph.output = None
    except Exception as error:       # noqa: BLE001 -- a material must not stop a render
        graph.warnings.append(f"node tree could not be translated: {error!r}")
        graph.output = None
    return graph


def _output_node(tree, output_types):
    """Cycles' choice: target Cycles over All, then the active one, then the first."""
    best, best_rank = None, None
    for node in tree.nodes:
        target = getattr(node, "target", "ALL")
        if node.type not in output_types or target not in ("ALL", "CYCLES"):
            continue
        rank = (target == "CYCLES", bool(node.is_active_output))
        if best is None or rank > best_rank:
            best, best_rank = node, rank
    return best


def _available(socket):
    return socket.enabled and not getattr(socket, "is_unavailable", False)


def _label(node):
    return node.label or node.name


def _socket(sockets, identifier):
    return next((s for s in sockets if s.identifier == identifier), None)


def _implicit(socket):
    """An input whose unlinked value Blender replaces by something per hit."""
    node = socket.node
    if node.type in _GROUPS:            # group inputs may ask for one (Default Input)
        tree = node.node_tree
        items = tree.interface.items_tree if tree is not None else ()
        item = next((i for i in items if getattr(i, "identifier", None) == socket.identifier), None)
        return getattr(item, "default_input", "VALUE") != "VALUE"
    return bool(socket.hide_value) and socket.type == VECTOR and (
        node.type.startswith("TEX_") or socket.identifier in _IMPLICIT)


def _own(socket):
    """The value an unlinked input holds (None: implicit, or none at all)."""
    if _implicit(socket) or not hasattr(socket, "default_value"):
        return None
    return _Const(plain(socket.default_value, socket.type), socket.type)


def _to(value, socket_type):
    """A value arriving at a socket of socket_type: constants converted."""
    if isinstance(value, _Const):
        return _Const(convert(value.value, value.type, socket_type),
                      COLOR if socket_type == SHADER else socket_type)
    return value


def _fallback(socket_type):
    value = zero(socket_type)
    return None if value is None else _Const(value, socket_type)


def _link(out, to_type):
    if out.type == to_type:
        return Link(out.index, out.socket)
    return Link(out.index, out.socket, out.type, to_type)


class _Scope:
    """One tree being walked: the material's, or a group's inside a group node."""

    def __init__(self, tree, parent=None, group_node=None):
        self.tree, self.parent, self.group_node = tree, parent, group_node
        self.path = parent.path + (group_node.name,) if parent else ()
        self.labels = parent.labels + (_label(group_node),) if parent else ()
        self.trees = (parent.trees if parent else ()) + (tree.as_pointer(),)

    def name(self, node):
        return " > ".join(self.labels + (_label(node),))


class _Translator:
    def __init__(self, graph, images):
        self.graph, self.images = graph, images
        self.index = {}         # (group node names..., node name) -> graph node index
        self.visiting = set()
        self.links = {}         # tree pointer -> {input socket pointer: link}

    def warn(self, text):
        if text not in self.graph.warnings:
            self.graph.warnings.append(text)

    def link_into(self, socket, tree):
        table = self.links.get(tree.as_pointer())
        if table is None:
            table = self.links[tree.as_pointer()] = {
                link.to_socket.as_pointer(): link for link in tree.links
                if link.is_valid and not link.is_muted
                and _available(link.from_socket) and _available(link.to_socket)}
        return table.get(socket.as_pointer())

    def arriving(self, socket, scope):
        """What reaches input `socket`: an _Out, a _Const, or None (nothing:
        the socket keeps its own value)."""
        link = self.link_into(socket, scope.tree)
        if link is None:
            return _own(socket)
        return _to(self.output(link.from_socket, scope), socket.type)

    def output(self, socket, scope):
        """The value of output `socket` (an _Out, a _Const or None)."""
        node = socket.node
        if node.type == "REROUTE":
            return self.arriving(node.inputs[0], scope)
        if node.mute:
            link = next((i for i in node.internal_links if i.to_socket.identifier == socket.identifier),
                        None)
            if link is None:
                return _fallback(socket.type)
            return _to(self.arriving(link.from_socket, scope), socket.type)
        if node.type in _GROUPS:
            return self.group_output(node, socket, scope)
        if node.type == "GROUP_INPUT":
            outer = _socket(scope.group_node.inputs, socket.identifier) if scope.group_node else None
            if outer is None:
                return _fallback(socket.type)
            return _to(self.arriving(outer, scope.parent), socket.type)
        index = self.node(node, scope)
        if index is None:
            return _fallback(socket.type)
        if node.type == "TEX_COORD" and socket.identifier in ("UV", "Generated"):
            self.graph.needs.add("uv:" if socket.identifier == "UV" else "generated")
        return _Out(index, socket.identifier, socket.type)

    def group_output(self, node, socket, scope):
        name, tree = scope.name(node), node.node_tree
        if tree is None or getattr(tree, "is_missing", False):
            self.warn(f"group node '{name}' has no node group (or its library is missing); "
                      f"its outputs are zero")
            return _fallback(socket.type)
        if tree.as_pointer() in scope.trees:
            self.warn(f"node group '{tree.name}' contains itself (group node '{name}'); its outputs are zero")
            return _fallback(socket.type)
        outputs = [n for n in tree.nodes if n.type == "GROUP_OUTPUT"]
        out = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
        if out is None:
            self.warn(f"node group '{tree.name}' (group node '{name}') has no Group Output; "
                      f"its outputs are zero")
            return _fallback(socket.type)
        inner = _socket(out.inputs, socket.identifier)
        if inner is None:
            return _fallback(socket.type)
        return _to(self.arriving(inner, _Scope(tree, scope, node)), socket.type)

    def node(self, node, scope):
        """The graph index of a real node, added after everything it reads."""
        key = scope.path + (node.name,)
        if key in self.index:
            return self.index[key]
        name = scope.name(node)
        if key in self.visiting:        # invalid links already break cycles; kept as a guard
            self.warn(f"node '{name}' depends on itself; reading zero instead")
            return None
        self.visiting.add(key)
        inputs = {}
        for socket in node.inputs:
            if _available(socket):
                value = self.reader_value(socket, scope, name)
                if value is not None:
                    inputs[socket.identifier] = value
        self.visiting.discard(key)
        try:
            props = node_props(node, self.images)
        except Exception as error:   # noqa: BLE001 -- unusual (add-on) nodes
            self.warn(f"settings of node '{name}' could not be read: {error!r}")
            props = {}
        index = self.index[key] = self.graph.add(Node(node.type, inputs, props, name))
        self.note_needs(node, inputs)
        self.note_approximations(node, inputs, name)
        return index

    def note_approximations(self, node, inputs, name):
        """Warn about what a node renders only in part (as the README lists)."""
        weight = inputs.get("Subsurface Weight") if node.type == "BSDF_PRINCIPLED" else None
        if node.type == "SUBSURFACE_SCATTERING" or (weight is not None and (
                not isinstance(weight, (int, float)) or weight > 0)):
            self.warn(f"node '{name}': subsurface scattering renders as diffuse reflection of its colour")

    def reader_value(self, socket, scope, name):
        """What Node.inputs holds for input `socket` of the node called `name`:
        a Link, a plain value, or None (left out)."""
        value = self.arriving(socket, scope)
        if value is None:
            value = _own(socket)
        if isinstance(value, _Out):
            return _link(value, socket.type)
        if value is None:
            return None
        if _implicit(socket) or not hasattr(socket, "default_value"):
            return self.constant_node(value, socket, name)
        return value.value

    def constant_node(self, value, socket, name):
        """A constant for a socket that cannot hold one: a node linked to it."""
        if socket.type == VECTOR:
            x, y, z = convert(value.value, value.type, VECTOR)
            node, out, out_type = Node("COMBXYZ", {"X": x, "Y": y, "Z": z}), "Vector", VECTOR
        elif socket.type in (COLOR, SHADER):
            color = convert(value.value, value.type, COLOR)
            node, out, out_type = Node("RGB", props={"color": color}), "Color", COLOR
        else:
            number = convert(value.value, value.type, FLOAT)
            node, out, out_type = Node("VALUE", props={"value": number}), "Value", FLOAT
        node.name = f"{name}: {socket.name} (constant)"
        return _link(_Out(self.graph.add(node), out, out_type), socket.type)

    def note_needs(self, node, inputs):
        """The per-hit data a node reads, for ShaderGraph.needs."""
        kind, needs = node.type, self.graph.needs
        if kind == "UVMAP":
            needs.add(f"uv:{node.uv_map}")
        elif kind == "NORMAL_MAP" and node.space == "TANGENT":
            needs.update((f"uv:{node.uv_map}", f"tangent:{node.uv_map}"))
        elif kind == "TANGENT":
            needs.update((f"uv:{node.uv_map}", f"tangent:{node.uv_map}") if node.direction_type == "UV_MAP"
                         else ("generated",))
        elif kind == "NEW_GEOMETRY":
            needs.add("generated")          # its Tangent (nodes_input.radial_tangent)
        elif kind == "VERTEX_COLOR":
            needs.add(f"color:{node.layer_name}")
        elif kind == "ATTRIBUTE" and node.attribute_type == "GEOMETRY":
            if node.attribute_name:         # no name reads zero (the shader's own rule)
                needs.add(f"color:{node.attribute_name}")
        elif kind == "ATTRIBUTE" and node.attribute_type in ("OBJECT", "INSTANCER"):
            needs.add(f"{node.attribute_type.lower()}:{node.attribute_name}")      # object_attributes.py
        elif kind == "ATTRIBUTE":
            self.warn(f"Attribute node '{node.name}' of type {node.attribute_type.replace('_', ' ').title()} "
                      "is not supported; it reads zero")
        elif kind == "TEX_IMAGE" and "Vector" not in inputs:
            needs.add("uv:")
        elif kind in _PROCEDURAL and "Vector" not in inputs:
            needs.add("generated")
