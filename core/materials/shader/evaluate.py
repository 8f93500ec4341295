"""Running a ShaderGraph over a batch of hits.

Nodes run in the graph's order, each once per batch, on whole arrays (in
the spirit of Cycles' SVM, which runs a compiled node program per shading
point: here one program step is one numpy pass over every hit). A node's
evaluator (core/shader/nodes_*.py, looked up by ``Node.kind``) receives an
``Inputs`` accessor and the ``Geometry`` of the batch, and returns its
outputs by socket identifier. Values keep the smallest shape that holds
them: a socket fed by constants stays a scalar or a 3-vector, so a material
without textures costs a few scalar operations however many hits it shades.

Nodes the engine does not know give their outputs' defaults (zero, black,
an empty closure) with one warning per node type; a failing node does the
same with its error in the warning. No graph raises.
"""

import numpy as np

from ...util.errors import context
from .closure import Closure
from .graph import BOOL, COLOR, FLOAT, INT, SHADER, VECTOR, Link

LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)   # Blender's default scene luma (Rec.709)

EVALUATORS = {}     # Node.kind -> function(inputs, geom, node) -> {output identifier: value}
APPROXIMATED = {}   # Node.kind -> what its evaluator leaves out (warned once per material)


def node(*kinds, approximated=None):
    """Register an evaluator for the node kinds; ``approximated``: what it
    leaves out of Cycles' node, for the warning of a material that uses it."""
    def register(fn):
        for kind in kinds:
            EVALUATORS[kind] = fn
            if approximated:
                APPROXIMATED[kind] = approximated
        return fn
    return register


def f32(x):
    return np.asarray(x, np.float32)


def vec(x):
    """A colour or vector value: always 2-D, (1, 3) for a constant, (N, 3) per hit,
    so it is never mistaken for three hits' floats."""
    v = f32(x)
    return v.reshape(1, 3) if v.ndim < 2 else v


BLACK = np.zeros((1, 3), np.float32)


def as_float(v):
    """A value as a float ((), (1,) or (N,)): vectors by the mean of their
    components (colours are converted by luminance on their links)."""
    if isinstance(v, Closure):
        return f32(0)
    v = f32(v)
    if v.ndim == 2:
        return v.mean(axis=-1)
    return v


def as_color(v):
    """A value as a colour/vector ((1, 3) or (N, 3)); floats repeat into three."""
    if isinstance(v, Closure):
        return BLACK
    v = f32(v)
    if v.ndim == 2:
        return v
    return np.repeat(v.reshape(-1, 1), 3, axis=1)


def convert(value, from_type, to_type):
    """Blender's implicit conversion along a link between two socket types."""
    if not from_type or not to_type or from_type == to_type:
        return value
    if to_type == SHADER:
        # A colour into a shader socket is an emission in Cycles.
        if isinstance(value, Closure):
            return value
        return Closure(emission=as_color(value))
    if from_type == SHADER:
        return f32(0) if to_type in (FLOAT, INT, BOOL) else BLACK
    if to_type in (FLOAT, INT, BOOL):
        v = f32(value)
        if v.ndim == 2:
            v = (v * LUMA).sum(axis=-1) if from_type == COLOR else v.mean(axis=-1)
        if to_type == INT:
            v = np.trunc(v)
        elif to_type == BOOL:
            v = (v > 0).astype(np.float32)
        return v
    if to_type in (COLOR, VECTOR):
        return as_color(value)
    return value


class Inputs:
    """Input values of one node: links resolved, defaults from the socket."""

    def __init__(self, values, node_, shader=None):
        self._values = values
        self._node = node_
        self._shader = shader

    def linked(self, name):
        return isinstance(self._node.inputs.get(name), Link)

    def raw(self, name, default=0.0):
        v = self._node.inputs.get(name, default)
        if isinstance(v, Link):
            out = self._values[v.node].get(v.socket)
            if out is None:     # an output the node did not give: its default, zero
                return f32(0)
            return convert(out, v.from_type, v.to_type)
        if v is None:
            v = default
        v = f32(v)
        return v.reshape(1, -1) if v.ndim == 1 else v

    def float(self, name, default=0.0):
        return as_float(self.raw(name, default))

    def color(self, name, default=(0.0, 0.0, 0.0)):
        return as_color(self.raw(name, default))

    vector = color

    def closure(self, name):
        v = self.raw(name, 0.0)
        if isinstance(v, Closure):
            return v
        return Closure()

    def prop(self, name, default=None):
        return self._node.props.get(name, default)

    def at(self, name, geom, kind="float"):
        """Input ``name`` evaluated again on other hits (the Bump node's moved
        copies): the nodes before its source run once more on ``geom``."""
        link = self._node.inputs.get(name)
        if not isinstance(link, Link) or self._shader is None:
            return self.float(name) if kind == "float" else self.color(name)
        values = self._shader.outputs(geom, stop=link.node + 1)
        v = values[link.node].get(link.socket)
        v = f32(0) if v is None else convert(v, link.from_type, link.to_type)
        return as_float(v) if kind == "float" else as_color(v)


class CompiledShader:
    """A graph ready to run on batches; built once per material per export."""

    def __init__(self, graph, images=None, warn=None):
        self.graph = graph
        self.images = images or {}
        self._warn = warn or (lambda text: None)
        self._warned = set()
        for text in graph.warnings:
            self.warn(text)
        for n in graph.nodes:
            if n.kind not in EVALUATORS:
                fallback = "renders as a grey diffuse surface" if _is_bsdf(n.kind) else \
                    "it gives its default outputs"
                self.warn_once(n.kind, f"node '{n.name or n.kind}' ({n.kind}) is not supported; {fallback}")
            elif n.kind in APPROXIMATED:
                self.warn_once(n.kind, f"node '{n.name or n.kind}' ({n.kind}): {APPROXIMATED[n.kind]}")
        # Outputs some node reads: an Image Texture un-premultiplies its colour
        # only when its Alpha output is used, as Cycles does.
        self.read_outputs = {(v.node, v.socket) for n in graph.nodes for v in n.inputs.values()
                             if isinstance(v, Link)}
        if graph.output is not None:
            self.read_outputs.add((graph.output.node, graph.output.socket))
        self.index = {id(n): i for i, n in enumerate(graph.nodes)}
        self.uniform = not any(EVALUATORS.get(n.kind) in VARYING for n in graph.nodes)

    def warn(self, text):
        """Through the caller's warn, which names the material, world or light."""
        self._warn(text)

    def warn_once(self, key, text):
        if key not in self._warned:
            self._warned.add(key)
            self.warn(text)

    def outputs(self, geom, stop=None):
        """Every node's outputs on the batch ``geom`` (the first ``stop``
        nodes' if given): a list of dicts."""
        values = []
        for n in self.graph.nodes[:stop]:
            fn = EVALUATORS.get(n.kind)
            if fn is None and _is_bsdf(n.kind):
                fn = _unknown_bsdf
            out = {}
            if fn is not None:
                try:
                    with np.errstate(all="ignore"):
                        out = fn(Inputs(values, n, self), geom, n, self) or {}
                except Exception as exc:   # noqa: BLE001 -- a node must never fail the render
                    self.warn_once(("error", n.kind),
                                   f"node '{n.name or n.kind}' failed ({type(exc).__name__}: {exc}); "
                                   f"it gives its default outputs")
                    out = {}
            values.append({k: _finite(v) for k, v in out.items()})
        return values

    def closure(self, geom):
        """The closure reaching the output, on the batch ``geom``."""
        link = self.graph.output
        if link is None:
            return Closure()
        with context("material", f"'{self.graph.name}'"):
            values = self.outputs(geom)
        v = values[link.node].get(link.socket)
        if v is None:
            return Closure()
        return convert(v, link.from_type or SHADER, SHADER)


def _finite(v):
    if isinstance(v, Closure):
        for k, a in v.fields.items():
            if not np.isfinite(a).all():
                v.fields[k] = np.nan_to_num(a, nan=0.0, posinf=0.0, neginf=0.0)
        return v
    v = f32(v)
    if not np.isfinite(v).all():
        v = np.nan_to_num(v, nan=0.0, posinf=0.0, neginf=0.0)
    return v


# Evaluators whose result depends on the hit (filled by the node modules):
# a graph without any of them is the same at every hit.
VARYING = set()


def varying(fn):
    VARYING.add(fn)
    return fn


def _is_bsdf(kind):
    return kind.startswith("BSDF_") or kind.endswith("_BSDF")


def _unknown_bsdf(inp, geom, n, sh):
    """A BSDF the engine does not know: diffuse of its Color input (grey without one)."""
    color = inp.color("Color", (0.8, 0.8, 0.8)) if "Color" in n.inputs else vec((0.8, 0.8, 0.8))
    return {"BSDF": Closure.bsdf(1.0, None, diffuse=np.clip(color, 0, None))}
