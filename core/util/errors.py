"""Where an error inside a frame happened, for the report a user sees.

Code that knows what it is working on (a frame's stage, a material's graph)
wraps that work in ``context(kind, name)``. An exception leaving it carries a
note (PEP 678) such as ``stage: spatial reuse``; ``describe`` turns the
exception and its notes into one line for Blender's report. Notes are part of
the exception, so they survive worker threads and the twin process's pickle.
Only the innermost context of each kind is noted.
"""

from contextlib import contextmanager

_PREFIX = "restir-gi "


@contextmanager
def context(kind, name):
    """Note ``kind: name`` on an exception raised inside, unless a context of
    the same kind nearer to the error noted one already."""
    try:
        yield
    except Exception as exc:
        if noted(exc, kind) is None:
            exc.add_note(f"{_PREFIX}{kind}: {name}")
        raise


def noted(exc, kind):
    """The name noted on ``exc`` for ``kind``, or None."""
    for note in getattr(exc, "__notes__", ()):
        if note.startswith(_PREFIX + kind + ": "):
            return note[len(_PREFIX) + len(kind) + 2:]
    return None


def notes(exc):
    """{kind: name} of every context noted on ``exc``."""
    out = {}
    for note in getattr(exc, "__notes__", ()):
        if note.startswith(_PREFIX) and ": " in note:
            kind, name = note[len(_PREFIX):].split(": ", 1)
            out[kind] = name
    return out


def describe(exc):
    """One line: the error's type and message, then where it happened, e.g.
    ``AttributeError: ... (stage: G-buffer; material: 'Screen')``."""
    text = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    where = "; ".join(f"{kind}: {name}" for kind, name in notes(exc).items())
    return f"{text} ({where})" if where else text
