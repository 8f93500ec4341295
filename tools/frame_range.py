"""Frame ranges as the command line gives them: 'A-B', 'A..B' (Blender's -f
notation) or 'A'; shared by render.py and farm.py (no bpy here)."""

from __future__ import annotations

import re


def parse_range(text: str) -> tuple[int, int] | None:
    """'A-B', 'A..B' or 'A' -> (A, B); None if malformed or empty (A > B)."""
    m = re.fullmatch(r"\s*(-?\d+)\s*(?:(?:-|\.\.)\s*(-?\d+)\s*)?", text)
    if m is None:
        return None
    a = int(m.group(1))
    b = int(m.group(2)) if m.group(2) is not None else a
    return (a, b) if a <= b else None


def runs(frames: list[int], step: int = 1) -> list[tuple[int, int]]:
    """Consecutive frames (``step`` apart) grouped into (first, last) runs."""
    out: list[tuple[int, int]] = []
    for f in frames:
        if out and f == out[-1][1] + step:
            out[-1] = (out[-1][0], f)
        else:
            out.append((f, f))
    return out


def chunks(first: int, last: int, size: int) -> list[tuple[int, int]]:
    """first..last in chunks of ``size`` frames."""
    return [(a, min(a + size - 1, last)) for a in range(first, last + 1, size)]
