"""core/util/checksum.py: equal states give equal checksums, and a change
anywhere reachable (an array's bytes, shape or type, a plain value, a
dataclass field, an attribute) changes it."""

import copy
from dataclasses import dataclass

import numpy as np

from restir_gi.core.util.checksum import checksum


@dataclass
class Stored:
    data: np.ndarray
    count: int
    keys: list


class Holder:
    def __init__(self):
        self.stored = Stored(np.arange(12, dtype=np.float32).reshape(4, 3), 3, ["a", ("b", 2)])
        self.flags = np.array([True, False, True])
        self.extra = {"x": 1.5, "none": None}
        self.again = self.stored        # a shared reference
        self.me = self                  # a cycle


def test_equal_states_agree_and_any_change_is_seen():
    base = Holder()
    assert checksum(base) == checksum(copy.deepcopy(base))
    edits = [
        lambda h: h.stored.data.__setitem__((2, 1), 7.25),
        lambda h: setattr(h.stored, "data", h.stored.data.reshape(3, 4)),
        lambda h: setattr(h.stored, "data", h.stored.data.astype(np.float64)),
        lambda h: setattr(h.stored, "count", 4),
        lambda h: h.stored.keys.append("c"),
        lambda h: h.flags.__setitem__(1, True),
        lambda h: h.extra.__setitem__("x", 1.25),
        lambda h: setattr(h, "new", 0),
    ]
    seen = {checksum(base)}
    for edit in edits:
        h = copy.deepcopy(base)
        edit(h)
        value = checksum(h)
        assert value not in seen
        seen.add(value)


def test_non_contiguous_arrays_count_by_their_values():
    a = np.arange(20, dtype=np.int32)
    assert checksum(a[::2]) == checksum(a[::2].copy()) != checksum(a[1::2])
