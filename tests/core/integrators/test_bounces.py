"""Bounce limits per kind (core/integrators/bounces.py): the Bounces value,
the kind of a sampled ray, and the counting that ends paths. Their effect on
images is compared with Cycles in tests/oracle/test_light_paths_vs_cycles.py."""

import pickle

import numpy as np

from restir_gi.core.bsdfs import bsdf
from restir_gi.core.integrators.bounces import (DIFFUSE, GLOSSY, TRANSMISSION, Bounces, binding, count,
                                      first_bounce_counts, per_kind)


def test_bounces_is_the_total_with_limits_per_kind():
    b = Bounces(8, 1, 4, 12)
    assert b == 8 and b + 1 == 9 and list(range(b)) == list(range(8))
    assert per_kind(b) == (1, 4, 12) and per_kind(6) == (6, 6, 6)
    assert binding(b) and not binding(Bounces(4, 4, 4, 12)) and not binding(4)
    assert b != Bounces(8, 2, 4, 12) and b == Bounces(8, 1, 4, 12)
    assert pickle.loads(pickle.dumps(b)) == b
    assert first_bounce_counts(3, Bounces(4)) is None
    assert first_bounce_counts(2, b).tolist() == [[1, 0, 0], [1, 0, 0]]
    assert first_bounce_counts(2, b, np.int8([GLOSSY, TRANSMISSION])).tolist() == [[0, 1, 0], [0, 0, 1]]


def test_count_ends_paths_past_a_limit():
    counts = np.zeros((4, 3), np.int16)
    limits = (1, 2, 0)
    kinds = np.array([DIFFUSE, GLOSSY, TRANSMISSION, DIFFUSE], np.int8)
    assert count(counts, kinds, limits).tolist() == [False, False, True, False]
    assert count(counts, kinds, limits).tolist() == [True, False, True, True]
    assert counts[:, DIFFUSE].tolist() == [2, 0, 0, 2]


def test_kind_of_each_sampled_lobe(rng):
    """Diffuse and specular lobes above the surface, a glass lobe above
    (reflection) and below (refraction)."""
    n = 4000
    wo = np.tile(np.float32([0.3, 0.0, 0.954]), (n, 1))
    u_lobe = rng.random(n).astype(np.float32)
    u = rng.random((n, 2)).astype(np.float32)
    params = bsdf.lobe_params(np.full((n, 3), 0.5, np.float32), np.full((n, 3), 0.5, np.float32),
                              np.full(n, 0.3, np.float32))
    wi, _, pdf = bsdf.sample(params, wo, u_lobe, u)
    kinds = bsdf.sampled_kinds(params, wo, wi, u_lobe)
    spec = u_lobe < params.p_spec
    ok = (pdf > 0) & (wi[:, 2] > 0)         # GGX reflections below the surface are discarded
    assert ok.mean() > 0.9
    assert (kinds[spec & ok] == GLOSSY).all() and (kinds[~spec & ok] == DIFFUSE).all()
    glass = bsdf.lobe_params(np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32),
                             np.full(n, 0.1, np.float32),
                             glass=(np.ones((n, 3), np.float32), np.ones((n, 3), np.float32),
                                    np.full(n, 1.5, np.float32), np.full(n, 0.1, np.float32)))
    wi, _, pdf = bsdf.sample(glass, wo, u_lobe, u)
    kinds = bsdf.sampled_kinds(glass, wo, wi, u_lobe)
    ok = pdf > 0
    below = wi[:, 2] < 0
    assert (kinds[ok & below] == TRANSMISSION).all() and (kinds[ok & ~below] == GLOSSY).all()
    assert 0.5 < (ok & below).mean() < 1.0       # most light refracts into glass
