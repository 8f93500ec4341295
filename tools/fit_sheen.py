#!/usr/bin/env python3
"""Tabulate the sheen lobe of core/bsdfs/sheen.py: writes ``core/bsdfs/sheen_ltc.npy``.

The model is the one Cycles' Principled sheen approximates (Zeltner, Burley
and Chiang 2022, "Practical Multiple-Scattering Sheen Using Linearly
Transformed Cosines"): a layer of unit thickness and unit density of
fibre-like SGGX microflakes (fibres along the normal, cross-section
sigma = roughness^2, so S = diag(1, 1, roughness^4)), non-absorbing,
specular microflakes, up to 16 scattering events. Light that leaves the top
is the sheen's reflection; light that leaves the bottom reaches the layers
below.

For each (roughness, cos theta) on a 32 x 32 grid this script follows
``--walkers`` random walks (numpy, all entries at once) and records

- R: the share that leaves through the top (the directional albedo),
- (a, b): the linearly transformed cosine with inverse matrix
  [[a, 0, b], [0, a, 0], [0, 0, 1]] in the frame of the incident direction
  that best explains the exit directions, by maximum likelihood (Newton's
  method on the log-likelihood, warm-started from the next rougher entry).

About 45 seconds with the default 40000 walkers per entry; R's standard
error is then below 0.0025.

Usage: python tools/fit_sheen.py [--walkers N] [--seed S]
"""

import argparse
import pathlib

import numpy as np

N_ROUGH = 32
N_COS = 32
MAX_BOUNCES = 16
MIN_EXITS = 200         # entries with fewer exits take their neighbour's shape


def grid():
    """Roughness and cos theta of the table's nodes (both i / 31, kept off 0)."""
    nodes = np.linspace(0.0, 1.0, N_COS)
    return np.maximum(nodes, 0.01), np.maximum(nodes, 0.01)


def sample_visible_flake(wi, alpha, u1, u2):
    """A flake normal of the fibre SGGX (ellipsoid semi-axes alpha, alpha,
    1 / alpha) seen from wi, by mapping the ellipsoid to the unit sphere."""
    v = np.stack([wi[:, 0] / alpha, wi[:, 1] / alpha, wi[:, 2] * alpha], 1)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    t1 = np.where((np.abs(v[:, 2]) < 0.999)[:, None], np.cross(v, [0.0, 0.0, 1.0]), np.cross(v, [1.0, 0.0, 0.0]))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(v, t1)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    y = p1[:, None] * t1 + p2[:, None] * t2 + np.sqrt(np.maximum(1 - p1 * p1 - p2 * p2, 0))[:, None] * v
    m = np.stack([y[:, 0] / alpha, y[:, 1] / alpha, y[:, 2] * alpha], 1)
    return m / np.linalg.norm(m, axis=1, keepdims=True)


def walk(cos, alpha, rng):
    """Random walks entering along (sin, 0, cos); returns (reflected (N,) bool,
    exit directions (N, 3))."""
    n = len(cos)
    d = np.stack([-np.sqrt(1 - cos * cos), np.zeros(n), -cos], 1)     # propagation direction
    depth = np.zeros(n)                                                 # 0: top, 1: bottom
    out = np.zeros((n, 3))
    reflected = np.zeros(n, bool)
    live = np.arange(n)
    for _ in range(MAX_BOUNCES + 1):
        dl, al = d[live], alpha[live]
        sigma_t = np.sqrt(dl[:, 0] ** 2 + dl[:, 1] ** 2 + al ** 4 * dl[:, 2] ** 2)
        t = -np.log1p(-rng.random(len(live))) / np.maximum(sigma_t, 1e-300)
        depth[live] += t * -dl[:, 2]
        up = depth[live] < 0
        reflected[live[up]] = True
        out[live[up]] = dl[up]
        keep = (depth[live] >= 0) & (depth[live] <= 1)
        live = live[keep]
        if len(live) == 0:
            break
        wi = -d[live]
        m = sample_visible_flake(wi, alpha[live], rng.random(len(live)), rng.random(len(live)))
        d[live] = 2 * np.sum(m * wi, 1)[:, None] * m - wi
    return reflected, out


def fit_ltc(w, start):
    """(a, b) maximising sum log D(w) of the LTC D(w) = z a^2 / (pi Q^2),
    Q = (a x + b z)^2 + (a y)^2 + z^2, over exit directions w (K, 3)."""
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    a, b = start
    n = len(w)

    def loglik(a, b):
        q = (a * x + b * z) ** 2 + (a * y) ** 2 + z * z
        return 2 * n * np.log(a) - 2 * np.sum(np.log(q))

    cur = loglik(a, b)
    for _ in range(60):
        s = a * x + b * z
        q = s * s + (a * y) ** 2 + z * z
        qa, qb = 2 * s * x + 2 * a * y * y, 2 * s * z
        qaa, qab, qbb = 2 * (x * x + y * y), 2 * x * z, 2 * z * z
        g = np.array([2 * n / a - 2 * np.sum(qa / q), -2 * np.sum(qb / q)])
        h_ab = -2 * np.sum(qab / q - qa * qb / q ** 2)
        h = np.array([[-2 * n / a ** 2 - 2 * np.sum(qaa / q - qa * qa / q ** 2), h_ab],
                      [h_ab, -2 * np.sum(qbb / q - qb * qb / q ** 2)]])
        try:
            step = -np.linalg.solve(h, g)
        except np.linalg.LinAlgError:
            step = g * 1e-3
        if g @ step <= 0:           # not an ascent direction: follow the gradient
            step = g * 1e-3 / max(np.abs(g).max(), 1e-12)
        t = 1.0
        while t > 1e-6:
            na, nb = a + t * step[0], b + t * step[1]
            if na > 1e-4:
                new = loglik(na, nb)
                if new >= cur:
                    break
            t *= 0.5
        else:
            break
        done = abs(new - cur) < 1e-9 * abs(cur) + 1e-12
        a, b, cur = na, nb, new
        if done:
            break
    return a, b


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walkers", type=int, default=40000)
    ap.add_argument("--seed", type=int, default=2022)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    rough, cos = grid()
    table = np.zeros((N_ROUGH, N_COS, 3))
    for i in range(N_ROUGH - 1, -1, -1):      # rough to smooth: each fit starts from the rougher one
        c = np.repeat(cos, args.walkers)
        refl, out = walk(c, np.full(len(c), rough[i]), rng)
        refl, out = refl.reshape(N_COS, -1), out.reshape(N_COS, args.walkers, 3)
        table[i, :, 2] = refl.mean(axis=1)
        for j in range(N_COS):
            w = out[j][refl[j]]
            start = tuple(table[i + 1, j, :2]) if i + 1 < N_ROUGH else (1.0, 0.0)
            table[i, j, :2] = fit_ltc(w, start) if len(w) >= MIN_EXITS else start
        print(f"roughness {rough[i]:.3f}: R {table[i, 0, 2]:.3f}..{table[i, -1, 2]:.3f} "
              f"a {table[i, :, 0].min():.3f}..{table[i, :, 0].max():.3f} "
              f"b {table[i, :, 1].min():.3f}..{table[i, :, 1].max():.3f}", flush=True)
    path = pathlib.Path(__file__).resolve().parent.parent / "core" / "bsdfs" / "sheen_ltc.npy"
    np.save(path, table.astype(np.float32))
    print(path.name)


if __name__ == "__main__":
    main()
