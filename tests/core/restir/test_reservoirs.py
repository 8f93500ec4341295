"""The reservoir maths of ReSTIR GI (core/restir/reservoirs.py): weighted reservoir
sampling by ``merge``, the contribution weight set by ``finalize``, history
capping, the row helpers, and resampled importance sampling (RIS) built from
them: an unbiased estimator whose variance falls as more candidates are seen."""

import numpy as np
import pytest

from support.chi2 import pooled_chi2
from restir_gi.core.restir.reservoirs import Reservoirs, cap_history, choose, finalize, merge, target

ALPHA = 1e-3


def candidates(values, n):
    """Reservoirs of n rows whose sample is tagged by x2[:, 0] = values."""
    c = Reservoirs.empty(n)
    c.x2[:, 0] = values
    c.prim2[:] = 0
    return c


def stream(weights, trials, rng, M_src=1.0):
    """Stream candidates 0..K-1 with fixed weights into ``trials`` independent
    reservoirs; returns the reservoirs (x2[:, 0] is the chosen candidate)."""
    res = Reservoirs.empty(trials)
    for i, w in enumerate(weights):
        merge(res, candidates(float(i), trials), np.full(trials, w, np.float32),
              np.full(trials, M_src, np.float32), rng.random(trials, dtype=np.float32))
    return res


# --- (1) weighted reservoir sampling ---------------------------------------------------

def test01_merge_selects_in_proportion_to_weight(rng):
    """Each candidate ends up chosen with probability w_i / sum w (chi-square on
    the selection counts), whatever its position in the stream."""
    weights = np.array([0.5, 3.0, 1.0, 0.1, 2.0, 7.0, 0.25, 1.5])
    trials = 200_000
    res = stream(weights, trials, rng)
    counts = np.bincount(res.x2[:, 0].astype(int), minlength=len(weights))
    expected = weights / weights.sum() * trials
    p, stat, dof, note = pooled_chi2(counts, expected)
    assert p > ALPHA, (counts, expected, stat, dof, note)
    assert np.allclose(res.w_sum, weights.sum(), rtol=1e-5)
    assert (res.M == len(weights)).all()


def test02_merge_in_reverse_order(rng):
    """The same distribution when the heavy candidates come first."""
    weights = np.array([9.0, 4.0, 1.0, 0.5, 0.2])
    trials = 100_000
    res = stream(weights, trials, rng)
    counts = np.bincount(res.x2[:, 0].astype(int), minlength=len(weights))
    p, stat, dof, note = pooled_chi2(counts, weights / weights.sum() * trials)
    assert p > ALPHA, (counts, stat, dof, note)


def test03_worthless_weights_are_never_chosen(rng):
    """Zero, negative, NaN and infinite weights add nothing to w_sum and are
    never selected; their candidates still count in M."""
    weights = [1.0, 0.0, np.nan, 2.0, np.inf, -3.0, -np.inf, 0.5]
    trials = 50_000
    res = stream(weights, trials, rng)
    chosen = res.x2[:, 0].astype(int)
    assert set(np.unique(chosen)) <= {0, 3, 7}
    assert np.allclose(res.w_sum, 3.5, rtol=1e-6)
    assert np.isfinite(res.w_sum).all()
    assert (res.M == len(weights)).all()
    counts = np.bincount(chosen, minlength=8)[[0, 3, 7]]
    p, stat, dof, note = pooled_chi2(counts, np.array([1.0, 2.0, 0.5]) / 3.5 * trials)
    assert p > ALPHA, (counts, stat, dof, note)


def test04_merge_into_empty_row_with_zero_weight_keeps_nothing(rng):
    """A row that only saw worthless candidates has no sample, w_sum 0, and M
    counting them all."""
    res = Reservoirs.empty(4)
    for _ in range(3):
        taken = merge(res, candidates(1.0, 4), np.zeros(4, np.float32), np.full(4, 2.0, np.float32),
                      rng.random(4, dtype=np.float32))
        assert not taken.any()
    assert not res.has_sample.any()
    assert (res.w_sum == 0).all() and (res.M == 6).all()


def test05_M_accumulates_M_src(rng):
    """M adds each candidate's own M (a reused reservoir stands for many)."""
    n = 1000
    res = Reservoirs.empty(n)
    total = np.zeros(n, np.float32)
    for _ in range(5):
        m = rng.integers(0, 30, n).astype(np.float32)
        w = np.where(rng.random(n) < 0.3, 0.0, rng.random(n)).astype(np.float32)
        merge(res, candidates(0.0, n), w, m, rng.random(n, dtype=np.float32))
        total += m
    assert np.array_equal(res.M, total)


def test06_merge_copies_the_whole_sample(rng):
    """A replaced row takes every sample field of its candidate; the
    resampling state (w_sum, M, W) stays the row's own."""
    n = 8
    dst = Reservoirs.empty(n)
    src = Reservoirs.empty(n)
    for name in Reservoirs.SAMPLE_FIELDS:
        a = getattr(src, name)
        a[...] = (rng.integers(1, 100, a.shape)).astype(a.dtype)
    src.W[:] = 123.0
    taken = merge(dst, src, np.ones(n, np.float32), np.ones(n, np.float32), np.zeros(n, np.float32))
    assert taken.all()
    for name in Reservoirs.SAMPLE_FIELDS:
        assert np.array_equal(getattr(dst, name), getattr(src, name)), name
    assert (dst.W == 0).all() and (dst.w_sum == 1).all() and (dst.M == 1).all()


# --- (2) finalize and cap_history -------------------------------------------------------

def test07_finalize_biased_and_with_Z():
    res = Reservoirs.empty(6)
    res.w_sum[:] = [6.0, 6.0, 6.0, 0.0, 6.0, 6.0]
    res.M[:] = [3.0, 3.0, 0.0, 3.0, 3.0, 3.0]
    p_hat = np.float32([2.0, 0.0, 2.0, 2.0, np.nan, np.inf])
    finalize(res, p_hat)
    assert np.allclose(res.W, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert np.isfinite(res.W).all()
    Z = np.float32([2.0, 2.0, 2.0, 2.0, 0.0, 1.0])
    finalize(res, np.full(6, 0.5, np.float32), Z)
    assert np.allclose(res.W, [6.0, 6.0, 6.0, 0.0, 0.0, 12.0])


def test08_cap_history():
    """M above the cap is scaled down to it with w_sum, keeping w_sum / M (and
    so W) unchanged; rows at or below the cap are untouched."""
    res = Reservoirs.empty(4)
    res.M[:] = [5.0, 20.0, 40.0, 0.0]
    res.w_sum[:] = [1.0, 2.0, 8.0, 0.0]
    res.W[:] = [0.5, 0.25, 0.1, 0.0]
    cap_history(res, 20.0)
    assert np.allclose(res.M, [5.0, 20.0, 20.0, 0.0])
    assert np.allclose(res.w_sum, [1.0, 2.0, 4.0, 0.0])
    assert np.allclose(res.W, [0.5, 0.25, 0.1, 0.0])


def test09_target_is_nonnegative_luminance():
    lo = np.float32([[1, 1, 1], [0, 0, 0], [-1, -1, -1], [2, 0, 0]])
    t = target(lo)
    assert t[0] == pytest.approx(1.0, rel=1e-5)
    assert t[1] == 0 and t[2] == 0 and t[3] > 0


# --- (3) take / assign / clear ------------------------------------------------------------

def filled(n, rng):
    r = Reservoirs.empty(n)
    for f in ("x2", "ng2", "n2", "wo2", "lo", "w_sum", "M", "W"):
        getattr(r, f)[...] = rng.random(getattr(r, f).shape)
    r.prim2[:] = rng.integers(0, 50, n)
    r.seed[:] = rng.integers(0, 2**62, n).astype(np.uint64)
    r.age[:] = rng.integers(0, 10, n)
    return r


def test10_take_assign_clear(rng):
    a = filled(10, rng)
    idx = np.array([3, 3, 0, 9])
    t = a.take(idx)
    assert len(t) == 4
    for name in ("x2", "prim2", "seed", "age", "w_sum", "M", "W"):
        assert np.array_equal(getattr(t, name), getattr(a, name)[idx]), name
    t.M[0] = -5.0                              # a copy, not a view
    assert a.M[3] != -5.0

    b = filled(10, rng)
    before = a.copy()
    mask = np.zeros(10, bool)
    mask[[1, 4, 7]] = True
    a.assign(mask, b)
    for name in ("x2", "lo", "prim2", "seed", "age", "w_sum", "M", "W"):
        got, src, old = getattr(a, name), getattr(b, name), getattr(before, name)
        assert np.array_equal(got[mask], src[mask]), name
        assert np.array_equal(got[~mask], old[~mask]), name

    a.clear(mask)
    assert (a.M[mask] == 0).all() and (a.w_sum[mask] == 0).all() and (a.W[mask] == 0).all()
    assert not a.has_sample[mask].any() and not a.valid[mask].any()
    assert (a.lo[mask] == 0).all()
    assert np.array_equal(a.M[~mask], before.M[~mask])
    assert a.has_sample[~mask].all()
    assert a.nbytes == before.nbytes


# --- (4) resampled importance sampling ------------------------------------------------------

def f(x):
    """The integrand on [0, 1]: integral 1/3 + 1/2 * (1 - cos 6) / 6."""
    return x * x + 0.5 * np.sin(6.0 * x)


F_INTEGRAL = 1.0 / 3.0 + 0.5 * (1.0 - np.cos(6.0)) / 6.0


def ris(M, runs, rng):
    """f(y) W of one RIS estimate per run: M uniform candidates streamed through
    merge with w = p_hat / p_src, then W = w_sum / (M p_hat(y))."""
    p_hat = lambda x: np.abs(f(x)) ** 0.7 + 0.05  # noqa: E731  (close to |f|, not equal)
    res = Reservoirs.empty(runs)
    for _ in range(M):
        x = rng.random(runs)
        c = candidates(x, runs)
        merge(res, c, (p_hat(x) / 1.0).astype(np.float32), np.ones(runs, np.float32),
              rng.random(runs, dtype=np.float32))
    y = res.x2[:, 0].astype(np.float64)
    finalize(res, p_hat(y).astype(np.float32))
    return f(y) * res.W


@pytest.mark.parametrize("M", [1, 4, 32])
def test11_ris_is_unbiased(M, rng):
    est = ris(M, 100_000, rng)
    err = est.std() / np.sqrt(len(est))
    assert abs(est.mean() - F_INTEGRAL) < 4.0 * err, (est.mean(), F_INTEGRAL, err)


def test12_ris_variance_falls_with_M(rng):
    """More candidates, less variance (down to that of sampling p_hat exactly)."""
    v = [ris(M, 40_000, rng).var() for M in (1, 4, 16)]
    assert v[1] < 0.5 * v[0] and v[2] < 0.8 * v[1] and v[2] < 0.25 * v[0], v


def test13_choose_selects_in_proportion_to_weight(rng):
    """One-step selection among C candidates: frequencies follow w / sum w
    (chi-square), zero, negative and non-finite weights never win, rows
    without any weight choose nothing, and w_sum is the sum of clean weights."""
    n = 200_000
    w = np.array([0.5, 0.0, 2.0, 1.5, np.nan, -1.0], np.float32)
    weights = [np.full(n, x, np.float32) for x in w]
    choice, w_sum = choose(weights, rng.random(n, dtype=np.float32))
    clean = np.where(np.isfinite(w) & (w > 0), w, 0)
    counts = np.bincount(choice, minlength=len(w))
    assert counts[[1, 4, 5]].sum() == 0
    p, *_ = pooled_chi2(counts[clean > 0], n * clean[clean > 0] / clean.sum())
    assert p > 1e-3
    assert np.allclose(w_sum, clean.sum())
    # At the top of the range (u just below one) the last weighted candidate wins.
    top = choose(weights, np.full(n, 0.99999994, np.float32))[0]
    assert (top == 3).all()
    none = choose([np.zeros(4, np.float32), np.zeros(4, np.float32)], np.full(4, 0.5, np.float32))[0]
    assert (none == -1).all()


def test11_stored_reservoirs_keep_rows_within_their_rounding(rng):
    """The narrow whole-image store (core/restir/reservoirs.py) gives back
    positions, weights, counts, seeds and triangles exactly, unit vectors
    within 1e-4 rad, radiance within float16 rounding, zero vectors as zero."""
    from restir_gi.core.restir.reservoirs import StoredReservoirs
    n = 2000
    r = filled(n, rng)
    for f in ("ng2", "n2", "wo2"):
        v = rng.normal(size=(n, 3))
        v[:4] = [[0, 0, 1], [0, 0, -1], [-1, 0, 0], [0, 0, 0]]
        norm = np.linalg.norm(v, axis=1, keepdims=True)
        setattr(r, f, (v / np.where(norm > 0, norm, 1)).astype(np.float32))
    r.lo[:] = (rng.random((n, 3)) * 10.0 ** rng.integers(-3, 4, (n, 1))).astype(np.float32)
    r.lo[0] = 1e6                                   # beyond float16: stored as its largest
    store = StoredReservoirs.empty(n + 5)
    store.write_rows(5, n + 5, r)
    back = store.take(np.arange(5, n + 5))
    for name in ("x2", "prim2", "seed", "age", "w_sum", "M", "W"):
        assert np.array_equal(getattr(back, name), getattr(r, name)), name
    for name in ("ng2", "n2", "wo2"):
        a, b = getattr(r, name).astype(np.float64), getattr(back, name).astype(np.float64)
        assert np.array_equal(b[3], [0, 0, 0]) and np.array_equal(b[:3], a[:3]), name
        angle = 2 * np.arcsin(np.minimum(np.linalg.norm(a - b, axis=1) / 2, 1.0))
        assert angle[4:].max() < 1e-4, (name, angle.max())
    assert back.lo[0, 0] == 65504.0
    err = np.abs(back.lo[1:] - r.lo[1:])         # (below 6e-5 float16's steps are 2^-24)
    assert (err <= np.maximum(2.0 ** -11 * r.lo[1:], 2.0 ** -25) * (1 + 1e-6)).all()
    assert store.nbytes == (n + 5) * StoredReservoirs.bytes_per_row()
