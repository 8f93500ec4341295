"""A shader node's own settings and its socket values as plain data.

Helpers of node_graph.py, which walks the tree; everything here looks at one
node or one value.

Socket values (``plain``): floats (ints and booleans too), 3-tuples for
vectors and colours (alpha dropped, as Cycles drops it), strings for menu
sockets. Constants moving between sockets of different types are converted the
way Blender converts them (``convert``); linked values are converted by the
evaluator (``Link.from_type`` / ``to_type``).

Node settings (``node_props``): every RNA property a node type adds to the
base ``ShaderNode`` (``operation``, ``blend_type``, ``interpolation``, ...),
enums as their identifier, plus what cannot be read generically:

- ``image`` (Image and Environment Texture): the key from ``images.key`` or the
  image's name; ``object`` (Texture Coordinate): the object's name and
  ``object_matrix_inverse``, its world matrix inverted, row by row;
  ``texture_mapping``: the node's legacy mapping (Cycles still applies it).
- Value, RGB and Normal nodes keep their constant on an output socket:
  ``value``, ``color`` and ``direction``.
- Color Ramp: ``ramp`` with the elements and also ``table``, the ramp sampled
  at 256 evenly spaced positions in [0, 1] with Blender's own evaluation (all
  interpolation and colour modes): Cycles renders from such a table.
- RGB Curves, Vector Curves, Float Curve: ``curves``, each curve sampled at 256
  evenly spaced x in ``range``, the x range of all the curves' points (Cycles'
  table range; clipping is already in the samples), and ``extend``
  (``EXTRAPOLATED``: Cycles continues the end slopes outside the range;
  ``HORIZONTAL``: the end values). RGB Curves lists them as C, R, G, B and
  Blender applies C first: red out = R(C(red in)), the same for green and blue.
  Vector Curves lists X, Y, Z; Float Curve its one curve.
"""

import bpy

FLOAT, VECTOR, COLOR, SHADER, INT, BOOL = "VALUE", "VECTOR", "RGBA", "SHADER", "INT", "BOOLEAN"
SCALARS = (FLOAT, INT, BOOL)
TRIPLES = (VECTOR, COLOR)

# Blender's default colour configuration's luminance weights (linear Rec. 709),
# used for colour to float.
LUMINANCE = (0.2126, 0.7152, 0.0722)

TABLE_SIZE = 256        # Cycles' RAMP_TABLE_SIZE

_BASE = frozenset(p.identifier for p in bpy.types.ShaderNode.bl_rna.properties)
_CURVES = ("CURVE_RGB", "CURVE_VEC", "CURVE_FLOAT")
_OUTPUT_CONSTANTS = {"VALUE": ("value", FLOAT), "RGB": ("color", COLOR), "NORMAL": ("direction", VECTOR)}


def plain(value, socket_type):
    """A socket's default_value as a float, a 3-tuple or a string."""
    if isinstance(value, str):
        return value
    try:
        items = tuple(float(x) for x in value)
    except TypeError:
        return float(value)
    return items[:3] if socket_type == COLOR else items


def zero(socket_type):
    """Blender's fallback value of a socket type (None: there is none)."""
    if socket_type in SCALARS:
        return 0.0
    if socket_type in TRIPLES:
        return (0.0, 0.0, 0.0)
    return None


def convert(value, from_type, to_type):
    """A constant of type from_type as Blender passes it to a to_type socket.

    Float to colour or vector repeats it; colour to float is the luminance,
    vector to float the mean; colour and vector copy components; to an integer
    truncates, to a boolean is "> 0". A shader socket takes a colour (Blender
    puts an RGB node in front of it)."""
    if to_type == SHADER:
        to_type = COLOR
    if from_type == to_type or isinstance(value, str):
        return value
    if from_type in TRIPLES and isinstance(value, tuple):
        if to_type in TRIPLES:
            return value
        weights = LUMINANCE if from_type == COLOR else (1 / 3, 1 / 3, 1 / 3)
        value = sum(w * c for w, c in zip(weights, value))
    if isinstance(value, tuple):        # unknown wide types: keep what there is
        return value
    if to_type in TRIPLES:
        return (value, value, value)
    if to_type == INT:
        return float(int(value))
    if to_type == BOOL:
        return float(value > 0.0)
    return float(value)


def node_props(node, images):
    """The node's own settings as plain values (see the module notes)."""
    props = _struct_props(node, _BASE, images)
    kind = node.type
    if kind in _OUTPUT_CONSTANTS:
        key, socket_type = _OUTPUT_CONSTANTS[kind]
        props[key] = plain(node.outputs[0].default_value, socket_type)
    if kind == "VALTORGB":
        props["ramp"] = color_ramp(node.color_ramp)
    if kind in _CURVES:
        props.update(curve_tables(node.mapping, rgb=kind == "CURVE_RGB"))
    return props


def _struct_props(struct, skip, images, nested=True):
    props = {}
    for prop in struct.bl_rna.properties:
        name = prop.identifier
        if name in skip or name == "rna_type":
            continue
        try:
            value = getattr(struct, name)
        except (AttributeError, RuntimeError):     # properties that refuse to be read
            continue
        if prop.type == "ENUM":
            props[name] = tuple(sorted(value)) if prop.is_enum_flag else value
        elif prop.type in ("BOOLEAN", "INT", "FLOAT", "STRING"):
            props[name] = _nested_tuple(value) if getattr(prop, "is_array", False) else value
        elif prop.type == "POINTER":
            _pointer(props, name, value, images, nested, struct)
    return props


def _pointer(props, name, value, images, nested, struct=None):
    if name == "image":
        # An image sequence's file follows the scene frame through the node's image user.
        props[name] = images.key(value, getattr(struct, "image_user", None), images.frame) \
            if images is not None else (value.name if value else "")
    elif isinstance(value, bpy.types.Object) or (value is None and name == "object"):
        props[name] = value.name if value is not None else ""
        if value is not None:
            props[name + "_matrix_inverse"] = _nested_tuple(value.matrix_world.inverted())
    elif isinstance(value, bpy.types.ID):
        props[name] = value.name
    elif name == "texture_mapping" and nested and value is not None:
        props[name] = _struct_props(value, (), images, nested=False)


def _nested_tuple(value):
    try:
        return tuple(_nested_tuple(v) for v in value)
    except TypeError:
        return value


def color_ramp(ramp):
    elements = list(ramp.elements)
    return {"interpolation": ramp.interpolation, "color_mode": ramp.color_mode,
            "hue_interpolation": ramp.hue_interpolation,
            "positions": [float(e.position) for e in elements],
            "colors": [tuple(float(c) for c in e.color) for e in elements],
            "table": [tuple(float(c) for c in ramp.evaluate(i / (TABLE_SIZE - 1)))
                      for i in range(TABLE_SIZE)]}


def curve_tables(mapping, rgb):
    """Each curve of a CurveMapping sampled over the x range of all its points."""
    mapping.initialize()
    curves = list(mapping.curves)
    xs = [p.location[0] for c in curves for p in (c.points[0], c.points[-1])]
    lo, hi = min(xs), max(xs)
    if hi <= lo:                        # one vertical column of points: any width will do
        hi = lo + 1.0
    step = (hi - lo) / (TABLE_SIZE - 1)
    tables = [[float(mapping.evaluate(c, lo + i * step)) for i in range(TABLE_SIZE)] for c in curves]
    if rgb:                             # Blender keeps R, G, B, C
        tables = tables[3:] + tables[:3]
    return {"curves": tables, "range": (float(lo), float(hi)), "extend": mapping.extend}


def uses_nodes(datablock):
    """Whether a material, world or light renders through its node tree. Where
    ``use_nodes`` is deprecated (materials and worlds from Blender 5.0, lights
    from 5.2: their trees exist by default and always render, the switch is
    stuck on) the tree counts whenever there is one, and the property is not
    read (that warns); before, the datablock's own switch."""
    prop = datablock.bl_rna.properties.get("use_nodes")
    if prop is None or getattr(prop, "is_deprecated", False):
        return datablock.node_tree is not None
    return bool(datablock.use_nodes) and datablock.node_tree is not None
