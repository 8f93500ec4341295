"""The Metallic BSDF node's Fresnel (core/materials/shader/nodes_shader.py):
the conductor Fresnel against its closed forms, and the edge colours whose
Schlick curves have the mean of Cycles' F82 tint and of the conductor."""

import numpy as np

from restir_gi.core.bsdfs.fresnel import fresnel_dielectric
from restir_gi.core.materials.shader.nodes_shader import conductor_edge, conductor_fresnel, f82_edge


def test_conductor_fresnel_at_normal_incidence_and_without_extinction():
    eta, k = np.float32([0.2, 1.1, 2.757]), np.float32([3.9, 0.0, 3.867])
    f0 = conductor_fresnel(np.float32(1.0), eta, k)
    np.testing.assert_allclose(f0, ((eta - 1) ** 2 + k ** 2) / ((eta + 1) ** 2 + k ** 2), rtol=1e-5)
    cos = np.linspace(0.05, 1.0, 20).astype(np.float32)
    np.testing.assert_allclose(conductor_fresnel(cos, np.float32(1.5), np.float32(0.0)),
                               fresnel_dielectric(cos, np.float32(1.5))[0], atol=1e-5)
    assert np.isclose(conductor_fresnel(np.float32(1e-4), np.float32(2.0), np.float32(3.0)), 1.0, atol=1e-2)


def _schlick_mean(f0, edge):
    mu = (np.arange(20000) + 0.5) / 20000
    curve = f0[:, None] + (edge - f0)[:, None] * (1 - mu) ** 5
    return (curve * 2 * mu).mean(axis=-1)


def test_edge_colours_keep_the_fresnel_means():
    f0, tint = np.float32([0.9, 0.6, 0.2]), np.float32([1.0, 0.7, 0.3])
    mu = (np.arange(20000) + 0.5) / 20000
    m = 1 / 7
    b = (f0 + (1 - f0) * (1 - m) ** 5) * (1 - tint) / (m * (1 - m) ** 6)
    f82 = f0[:, None] + (1 - f0[:, None]) * (1 - mu) ** 5 - b[:, None] * mu * (1 - mu) ** 6
    np.testing.assert_allclose(_schlick_mean(f0, f82_edge(f0, tint)), (f82 * 2 * mu).mean(axis=-1), atol=2e-4)
    assert (f82_edge(f0, np.ones(3, np.float32)) == 1.0).all()     # no tint: Schlick's own curve
    # The node's default conductor: the edge keeps the mean. Gold's blue
    # (n 1.37, k 1.77) rises faster than any Schlick curve ending at one:
    # the edge stops at one, below the mean.
    eta, k = np.float32([[2.757, 2.513, 2.231], [0.18, 0.42, 1.37]]), np.float32([[3.867, 3.404, 3.009],
                                                                                 [3.42, 2.35, 1.77]])
    f0c, edge = conductor_edge(eta, k)
    exact = (conductor_fresnel(mu[None, None, :].astype(np.float32), eta[..., None], k[..., None]) * 2 * mu) \
        .mean(axis=-1)
    np.testing.assert_allclose(_schlick_mean(f0c[0], edge[0]), exact[0], atol=2e-3)
    np.testing.assert_allclose(_schlick_mean(f0c[1, :2], edge[1, :2]), exact[1, :2], atol=2e-3)
    assert edge[1, 2] == 1.0 and _schlick_mean(f0c[1, 2:], edge[1, 2:])[0] < exact[1, 2]
    assert (edge <= 1).all() and (edge >= 0).all()
