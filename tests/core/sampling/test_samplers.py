"""The hashed random numbers of core.sampling.samplers: deterministic, in [0, 1), uniform,
and independent across dimensions, pixels, samples, frames and seeds."""

import numpy as np
import pytest

from support.chi2 import pooled_chi2
from restir_gi.core.sampling import samplers

W, H = 256, 256
PIX = np.arange(W * H, dtype=np.int64)


def _seeds(seed=0, frame=0, sample=0):
    return samplers.path_seeds(seed, frame, PIX, sample)


def _uniformity_p(u, bins=64):
    counts = np.histogram(u, bins=bins, range=(0.0, 1.0))[0]
    p, *_ = pooled_chi2(counts, np.full(bins, len(u) / bins))
    return p


def _pair_p(a, b, bins=16):
    """Chi-square p-value of the joint histogram of (a, b) against independence and uniformity."""
    counts = np.histogram2d(a, b, bins=bins, range=[[0, 1], [0, 1]])[0]
    p, *_ = pooled_chi2(counts, np.full(counts.shape, len(a) / bins ** 2))
    return p


def test01_deterministic():
    s1, s2 = _seeds(7, 3, 5), _seeds(7, 3, 5)
    assert s1.dtype == np.uint64
    assert np.array_equal(s1, s2)
    for dim in (0, 1, 17, 300):
        assert np.array_equal(samplers.uniform(s1, dim), samplers.uniform(s2, dim))
    # Scalars and arrays hash alike: one path's seed can be recomputed alone.
    assert samplers.path_seeds(7, 3, 1234, 5) == s1[1234]
    assert samplers.uniform(s1[1234:1235], 9)[0] == samplers.uniform(s1, 9)[1234]


def test02_changes_with_every_key():
    base = _seeds(0, 0, 0)
    for other in (_seeds(1, 0, 0), _seeds(0, 1, 0), _seeds(0, 0, 1)):
        same = (samplers.uniform(base, 0) == samplers.uniform(other, 0)).mean()
        assert same < 1e-3
    assert len(np.unique(base)) == len(base)                # no two pixels share a seed
    # Keys are not interchangeable: moving a 1 or a 2 between seed, frame and
    # sample gives a new sequence every time.
    keys = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 2, 0), (2, 1, 0), (0, 1, 2), (0, 2, 1), (2, 0, 1)]
    first = {k: _seeds(*k)[:64].tobytes() for k in keys}
    assert len(set(first.values())) == len(keys)


_MASK = (1 << 64) - 1


def _inverse_mix64(h):
    """Python-int inverse of the SplitMix64 finaliser, to build extreme inputs."""
    def unshift(x, s):
        y = x
        for _ in range(64 // s + 1):
            y = x ^ (y >> s)
        return y & _MASK
    h = unshift(h, 31)
    h = (h * pow(int(samplers._M2), -1, 1 << 64)) & _MASK
    h = unshift(h, 27)
    h = (h * pow(int(samplers._M1), -1, 1 << 64)) & _MASK
    return unshift(h, 30)


def test03_range_and_dtype():
    s = _seeds(3, 0, 0)
    values = np.concatenate([samplers.uniform(s, d) for d in range(40)])
    assert values.dtype == np.float32
    assert values.min() >= 0.0 and values.max() < 1.0
    assert (values * (1 << 24) == np.floor(values * (1 << 24))).all()   # a 24-bit grid
    # Seeds whose hash is the largest and the smallest 64-bit value give the
    # extremes of the range: still below one, and zero.
    dim = 5
    for h, expected in ((_MASK, 1.0 - 2.0 ** -24), (0, 0.0)):
        seed = (_inverse_mix64(h) - (dim + 1) * int(samplers._GOLDEN)) & _MASK
        assert int(samplers.mix64(np.uint64(_inverse_mix64(h)))) == h
        assert samplers.uniform(np.array([seed], np.uint64), dim)[0] == np.float32(expected)
    u2 = samplers.uniform2(s, 5)
    assert u2.shape == (len(s), 2)
    assert np.array_equal(u2[:, 0], samplers.uniform(s, 5)) and np.array_equal(u2[:, 1], samplers.uniform(s, 6))


@pytest.mark.parametrize("dim", [0, 1, 8, 13, 63, 1000])
def test04_uniform(dim):
    u = samplers.uniform(_seeds(11, 2, 4), dim)
    assert _uniformity_p(u) > 0.001
    # The low bits are as uniform as the high ones (a sign of a full 24-bit mantissa).
    fine = (u * (1 << 24)).astype(np.int64) & 255
    counts = np.bincount(fine, minlength=256)
    p, *_ = pooled_chi2(counts, np.full(256, len(u) / 256))
    assert p > 0.001


def test05_independent_dimensions():
    s = _seeds(5, 0, 0)
    bound = 4.5 / np.sqrt(len(s))
    for d0, d1 in ((0, 1), (1, 2), (0, 8), (8, 16), (samplers.bounce_dim(0, samplers.D_BSDF_UV),
                                                     samplers.bounce_dim(0, samplers.D_BSDF_UV) + 1)):
        a, b = samplers.uniform(s, d0), samplers.uniform(s, d1)
        assert abs(np.corrcoef(a, b)[0, 1]) < bound
        assert _pair_p(a, b) > 0.001


def test06_independent_neighbouring_pixels_and_samples():
    bound = 4.5 / np.sqrt(W * H)
    u = samplers.uniform(_seeds(5, 0, 0), 0).reshape(H, W)
    right = (u[:, :-1].ravel(), u[:, 1:].ravel())
    up = (u[:-1, :].ravel(), u[1:, :].ravel())
    for a, b in (right, up):
        assert abs(np.corrcoef(a, b)[0, 1]) < bound
        assert _pair_p(a, b) > 0.001
    # Consecutive samples and frames of one pixel.
    v = samplers.uniform(_seeds(5, 0, 1), 0).reshape(H, W)
    f = samplers.uniform(_seeds(5, 1, 0), 0).reshape(H, W)
    for other in (v, f):
        assert abs(np.corrcoef(u.ravel(), other.ravel())[0, 1]) < bound
        assert _pair_p(u.ravel(), other.ravel()) > 0.001


def test07_pixel_grid_has_no_pattern():
    # The mean of each row and column of the image stays within noise: catches
    # hashes that leave structure along x or y.
    u = samplers.uniform(_seeds(9, 0, 0), 3).reshape(H, W).astype(np.float64)
    sd = np.sqrt(1 / 12)
    for axis, n in ((0, H), (1, W)):
        z = (u.mean(axis=axis) - 0.5) / (sd / np.sqrt(n))
        assert np.abs(z).max() < 5.0
        assert 0.7 < z.std() < 1.3


def test08_dimension_layout_does_not_overlap():
    offsets = [samplers.D_LIGHT_SELECT, samplers.D_LIGHT_UV, samplers.D_LIGHT_UV + 1, samplers.D_LOBE,
               samplers.D_BSDF_UV, samplers.D_BSDF_UV + 1, samplers.D_RR]
    assert len(set(offsets)) == len(offsets)
    assert max(offsets) < samplers.DIMS_PER_BOUNCE
    assert samplers.DIM_CAMERA + 4 <= samplers.DIM_BOUNCE_BASE
    used = [samplers.bounce_dim(b, o) for b in range(20) for o in offsets]
    assert len(set(used)) == len(used)
    assert min(used) >= samplers.DIM_BOUNCE_BASE


def test09_mix64_is_a_bijection_on_a_sample():
    x = np.arange(1 << 16, dtype=np.uint64) * np.uint64(0x100000001)
    assert len(np.unique(samplers.mix64(x))) == len(x)
    # Avalanche: flipping one input bit flips about half the output bits.
    rng = np.random.default_rng(1)
    x = rng.integers(0, 2 ** 63, 4096, dtype=np.uint64)
    for bit in (0, 17, 40, 63):
        diff = samplers.mix64(x) ^ samplers.mix64(x ^ np.uint64(1 << bit))
        flips = np.unpackbits(diff.view(np.uint8)).reshape(len(x), 64).sum(axis=1)
        assert 30 < flips.mean() < 34


def test10_radical_inverse():
    k = np.arange(6)
    assert np.allclose(samplers.radical_inverse(k, 2), [0, 1 / 2, 1 / 4, 3 / 4, 1 / 8, 5 / 8])
    assert np.allclose(samplers.radical_inverse(k, 3), [0, 1 / 3, 2 / 3, 1 / 9, 4 / 9, 7 / 9])


@pytest.mark.parametrize("count", [1, 5, 16])
def test11_stratified_light_uniforms(count):
    """Every sample of a stratified set is uniform on its own (so averages stay
    unbiased), and one set covers the selection axis in equal strata."""
    n_sets = 20000
    k = np.tile(np.arange(count), n_sets)
    seeds = _seeds()[: n_sets * count]
    s_sel = np.repeat(samplers.uniform(seeds[:n_sets], 1), count)
    s_uv = np.repeat(samplers.uniform2(seeds[:n_sets], 2), count, axis=0)
    u_sel, u = samplers.stratified_light_uniforms(k, np.full(len(k), count), s_sel, s_uv)
    assert u_sel.dtype == u.dtype == np.float32
    assert (u_sel >= 0).all() and (u_sel < 1).all() and (u >= 0).all() and (u < 1).all()
    for j in range(count):                     # sample j of every set: uniform
        rows = slice(j, None, count)
        assert _uniformity_p(u_sel[rows]) > 1e-3
        assert _pair_p(u[rows, 0], u[rows, 1]) > 1e-3
    one_set = np.sort(u_sel[:count].astype(np.float64))
    gaps = np.diff(np.concatenate([one_set, [one_set[0] + 1.0]]))
    assert np.allclose(gaps, 1.0 / count, atol=1e-6)


def test12_sobol_points_are_uniform_and_runs_stratified():
    """Each point of the Owen-scrambled Sobol sequence is uniform over the
    scrambles (so a mean of them stays unbiased); any two of its three
    dimensions put 2 to 4 of 768 points in each cell of a 16x16 grid; a
    shuffled index takes every aligned run of 16 indices to an aligned run,
    so the 16 points of a pixel's still put one in each cell of the 4x4,
    16x1 and 1x16 grids; a scalar index gives what one index per row gives;
    and the share of a pixel behind an edge from a still's first 16 points
    (sobol_jitter) has a fifth of the squared error of 16 independent
    points' (measured 0.0020 against 0.0129; the rotated R2 sequence used
    before: 0.0040)."""
    bits = samplers.scrambles(_seeds(3)[:20000], 0, 3)
    assert bits.dtype == np.uint32
    for index in (0, 1, 7, 123456789):
        u = samplers.sobol(index, bits, range(3))
        assert u.dtype == np.float32 and (u >= 0).all() and (u < 1).all()
        for a, b in ((0, 1), (0, 2), (1, 2)):
            assert _pair_p(u[:, a], u[:, b]) > 1e-3
        assert np.array_equal(u, samplers.sobol(np.full(len(bits), index), bits, range(3)))
    rng = np.random.default_rng(4)
    u = samplers.sobol(np.arange(768), np.tile(bits[:1], (768, 1)), range(3))
    for a in range(3):
        for b in range(a + 1, 3):
            cells = np.histogram2d(u[:, a], u[:, b], bins=16, range=[[0, 1], [0, 1]])[0]
            assert cells.min() >= 2 and cells.max() <= 4, (a, b, cells.min(), cells.max())
    for start in rng.integers(0, 1 << 26, 100) * 16:
        key = rng.integers(0, 1 << 32, dtype=np.uint64).astype(np.uint32)
        index = samplers.shuffled_index(np.arange(start, start + 16), np.full(16, key, np.uint32))
        assert len(np.unique(index >> np.uint32(4))) == 1 and len(np.unique(index & np.uint32(15))) == 16
        scramble = np.tile(rng.integers(0, 1 << 32, (1, 2), dtype=np.uint64).astype(np.uint32), (16, 1))
        u = samplers.sobol(index, scramble, samplers.SOBOL_CAMERA)
        for bins in ((4, 4), (16, 1), (1, 16)):
            cells = np.histogram2d(u[:, 0], u[:, 1], bins=bins, range=[[0, 1], [0, 1]])[0]
            assert (cells == 1).all() if bins == (4, 4) else (cells.max() == 1)
    # A straight edge through the pixel at a random angle and place; its
    # covered share from a 64x64 grid of point centres.
    n = 2000
    angle, cut = rng.uniform(0, np.pi, n), rng.uniform(-0.3, 0.3, n)
    normal = np.stack([np.cos(angle), np.sin(angle)], axis=1).astype(np.float32)

    def coverage(u):                                    # u (n, k, 2)
        return (np.einsum("nkc,nc->nk", u - 0.5, normal) > cut[:, None]).mean(axis=1)

    g = (np.arange(64, dtype=np.float32) + 0.5) / 64
    grid = np.stack(np.meshgrid(g, g), axis=-1).reshape(1, -1, 2)
    exact = coverage(np.broadcast_to(grid, (n, 4096, 2)))
    keys = rng.integers(0, 1 << 62, n, dtype=np.uint64)
    seq = np.stack([samplers.sobol_jitter(np.full(16, k, np.uint64), np.arange(16)) for k in keys])
    iid = rng.random((n, 16, 2)).astype(np.float32)
    err_seq, err_iid = coverage(seq) - exact, coverage(iid) - exact
    assert abs(err_seq.mean()) < 0.01 and abs(err_iid.mean()) < 0.01
    assert np.mean(err_seq ** 2) < np.mean(err_iid ** 2) / 4.0, (np.mean(err_seq ** 2), np.mean(err_iid ** 2))
