"""The Attribute node's Object and Instancer types: one value per placed object.

A material's graph asks for them as needs ``object:NAME`` and
``instancer:NAME`` (node_graph.py); each placed object then carries the value
of each, looked up as Cycles does: a custom property of the object, then of
its data, then a property path of the object (``color``, ``location``), then
of its data. Instancer looks on the object that instances this one (a
particle system's or vertex/face instancing's parent), or on the object
itself when it is not instanced. Numbers become grey (x, x, x, 1), arrays of
2 to 4 numbers a vector or colour (alpha 1 unless given); anything else, or
a missing name, reads zero, as in Cycles. The core reads them from
``scene.object_info`` under the need's name (core/materials/shader/geometry.py).
"""

import numbers

import numpy as np

PREFIXES = ("object:", "instancer:")
ZERO = (0.0, 0.0, 0.0, 0.0)


def split_needs(needs):
    """(corner data needs, per-object attribute needs) of a set of needs."""
    per_object = {n for n in needs if n.startswith(PREFIXES)}
    return needs - per_object, per_object


def object_attributes(inst, obj, needs):
    """Sorted ((need, (r, g, b, a)), ...) of one depsgraph instance."""
    if not needs:
        return ()
    out = []
    for need in sorted(needs):
        kind, name = need.split(":", 1)
        holder = obj
        if kind == "instancer" and inst is not None and getattr(inst, "is_instance", False) \
                and inst.parent is not None:
            holder = inst.parent
        out.append((need, lookup(holder, name)))
    return tuple(out)


def lookup(ob, name):
    """(r, g, b, a) of attribute ``name`` on object ``ob`` (zero when none)."""
    if not name:
        return ZERO
    data = getattr(ob, "data", None)
    for holder in (ob, data):
        if holder is None:
            continue
        try:
            value = holder.get(name)
        except (TypeError, AttributeError):
            value = None
        value = _rgba(value)
        if value is not None:
            return value
    for holder in (ob, data):
        if holder is None:
            continue
        try:
            value = _rgba(holder.path_resolve(name))
        except (ValueError, TypeError, AttributeError):
            continue
        if value is not None:
            return value
    return ZERO


def _rgba(value):
    if value is None or isinstance(value, str):
        return None
    if isinstance(value, numbers.Real):
        x = float(value)
        return (x, x, x, 1.0)
    try:
        items = [float(v) for v in value]
    except (TypeError, ValueError):
        return None
    if not 2 <= len(items) <= 4:
        return None
    return tuple(items + [0.0] * (3 - len(items))) + ((1.0,) if len(items) < 4 else ())


def attribute_tables(per_object):
    """{need: (O, 4) float32} from each object's ((need, rgba), ...); objects
    without a need read zero."""
    names = sorted({need for attrs in per_object for need, _ in attrs})
    tables = {name: np.zeros((len(per_object), 4), np.float32) for name in names}
    for i, attrs in enumerate(per_object):
        for need, value in attrs:
            tables[need][i] = value
    return tables
