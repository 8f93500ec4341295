"""Light path limits as Cycles counts them (Render > Light Paths > Max
Bounces): a total and one limit per kind of bounce, diffuse, glossy and
transmission.

Every continuation ray is of one kind, from the lobe that drew it: a ray
below the surface is transmission (glass refraction, translucency), above it
the specular and glass lobes give glossy rays and the diffuse and sheen lobes
diffuse ones. Transparent pass-through is not a bounce (core/integrators/transparency.py).
As in Cycles (whose kernel limits are the settings plus one), the ray that
takes a kind's count over its limit is still traced for the emission it
finds (weighted by MIS against the light sampled at its origin), and the path
ends at its hit; a path that reached its diffuse limit goes on through
glossy and transmission bounces. The total works the same way (path.py's
loop over bounces). The kind also picks the object ray visibility that
applies (Object > Visibility > Ray Visibility: Diffuse, Glossy,
Transmission). The kind of a sampled ray comes from bsdf.sampled_kinds,
next to the sampler whose lobe choice it follows.

``Bounces`` is the total limit as an int, so code that only needs the total
keeps using it as one, with the per-kind limits as attributes.
"""

import numpy as np

from ..bsdfs.bsdf import (  # noqa: F401
    KIND_DIFFUSE as DIFFUSE, KIND_GLOSSY as GLOSSY, KIND_TRANSMISSION as TRANSMISSION)
KIND_NAMES = ("diffuse", "glossy", "transmission")


class Bounces(int):
    """Max bounces in all (the int value) and per kind of bounce."""

    def __new__(cls, total, diffuse=None, glossy=None, transmission=None, volume=None):
        self = super().__new__(cls, int(total))
        self.per_kind = tuple(int(total if v is None else v) for v in (diffuse, glossy, transmission))
        # Scattering in media (core/integrators/media_path.py): None, the total.
        self.volume = None if volume is None else int(volume)
        return self

    def __reduce__(self):
        return (Bounces, (int(self), *self.per_kind, self.volume))

    def __eq__(self, other):
        if isinstance(other, Bounces):
            return int(self) == int(other) and self.per_kind == other.per_kind and self.volume == other.volume
        return int(self) == other

    def __ne__(self, other):
        return not self == other

    __hash__ = int.__hash__

    def __repr__(self):
        return "Bounces({}, diffuse={}, glossy={}, transmission={})".format(int(self), *self.per_kind)

    @property
    def binding(self):
        """True if a per-kind limit can end a path before the total does."""
        return min(self.per_kind) < int(self)


def per_kind(max_bounces):
    """(diffuse, glossy, transmission) limits of an int or a Bounces."""
    return getattr(max_bounces, "per_kind", (int(max_bounces),) * 3)


def binding(max_bounces):
    return bool(getattr(max_bounces, "binding", False))


def count(counts, kinds, limits):
    """Add each ray's bounce to its path's count of that kind (counts: (N, 3)
    int16, in place); True where the count went over its limit: the ray is
    traced for the emission it finds, and the path ends at its hit."""
    rows = np.arange(len(kinds))
    counts[rows, kinds] += 1
    return counts[rows, kinds] > np.asarray(limits, np.int16)[kinds]


def first_bounce_counts(n, max_bounces, kinds=None):
    """Counts (n, 3) of paths that made one bounce (ReSTIR GI's sample rays)
    of the given kinds (diffuse if None), or None when no per-kind limit binds."""
    if not binding(max_bounces):
        return None
    counts = np.zeros((n, 3), np.int16)
    if kinds is None:
        counts[:, DIFFUSE] = 1
    else:
        counts[np.arange(n), np.asarray(kinds, np.int64)] = 1
    return counts
