"""ReSTIR runs against a path-traced reference, statistically: independent
runs give the standard error of their mean, the reference film its own; the
means are compared by z-tests on the whole image and on blocks of pixels
(Sidak correction over the blocks)."""

import math
from statistics import NormalDist

import numpy as np

from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
from restir_gi.core.util.vectors import luminance

SIZE = 16               # image width and height


BLOCK = 4               # block side in pixels: (SIZE / BLOCK)^2 blocks


MAX_BOUNCES = 4


FRAMES = 6              # frames per ReSTIR run (the last one is compared)


ALPHA = 1e-3            # false-alarm rate of each test (whole family for the blocks)


def blocks(images):
    """(..., P) luminance images of a square image -> (..., B) block sums over
    BLOCK x BLOCK pixels."""
    b = math.isqrt(images.shape[-1]) // BLOCK
    lead = images.shape[:-1]
    return images.reshape(*lead, b, BLOCK, b, BLOCK).sum(axis=(-3, -1)).reshape(*lead, b * b)


class Reference:
    """Mean luminance per pixel (P,) and the variance of that mean (P,)."""

    def __init__(self, film):
        self.count = film.count
        self.mean = luminance(film.mean().reshape(-1, 3)).astype(np.float64)
        self.var_of_mean = film.variance_of_mean().reshape(-1).astype(np.float64)

    @property
    def var_1spp(self):
        """Per-pixel variance of one path-traced sample."""
        return self.var_of_mean * self.count


def restir_runs(ctx, runs, part="color", **kw):
    """Luminance of the last frame of ``runs`` independent ReSTIR runs, (runs, P)
    (of its colour, or of another part of the FrameResult)."""
    out = []
    for r in range(runs):
        restir = ReSTIRGI()
        settings = ReSTIRSettings(seed=1000 + r, max_bounces=MAX_BOUNCES, **kw)
        for f in range(FRAMES):
            result = restir.render_frame(ctx, settings, f)
        out.append(luminance(getattr(result, part)))
    return np.stack(out).astype(np.float64)


def z_scores(runs, ref_mean, ref_var_of_mean):
    """z of the difference between the column means of independent runs (rows)
    and a reference mean with a known variance."""
    se2 = runs.var(axis=0, ddof=1) / len(runs) + ref_var_of_mean
    return (runs.mean(axis=0) - ref_mean) / np.sqrt(np.maximum(se2, 1e-30))


def z_limit(tests):
    """Two-sided z threshold of a family of ``tests`` at level ALPHA (Sidak)."""
    per_test = 1.0 - (1.0 - ALPHA) ** (1.0 / tests)
    return NormalDist().inv_cdf(1.0 - 0.5 * per_test)


def assert_same_mean(runs, ref, what):
    """Image mean and block sums of the runs against the reference (pixels of
    one path-traced pass are independent, so variances of sums add up).
    ref: a Reference, or (mean, variance of the mean) per pixel."""
    mean, var_of_mean = (ref.mean, ref.var_of_mean) if isinstance(ref, Reference) else ref
    total = runs.sum(axis=1, keepdims=True)
    z_image = float(z_scores(total, mean.sum(), var_of_mean.sum())[0])
    z_blocks = z_scores(blocks(runs), blocks(mean), blocks(var_of_mean))
    n = runs.shape[1]
    se = (total.std(ddof=1) / math.sqrt(len(runs)) / n, math.sqrt(var_of_mean.sum()) / n)
    summary = (f"{what}: image mean {runs.mean():.5f} (+- {se[0]:.5f}) vs reference {mean.mean():.5f} "
               f"(+- {se[1]:.5f}), z = {z_image:.2f}; block z in [{z_blocks.min():.2f}, {z_blocks.max():.2f}]")
    print(summary)
    assert abs(z_image) < z_limit(1), summary
    assert np.abs(z_blocks).max() < z_limit(len(z_blocks)), (summary, np.round(z_blocks, 2))
