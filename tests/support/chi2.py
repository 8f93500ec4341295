"""Chi-square goodness-of-fit tests for samplers against their densities.

In the spirit of Mitsuba's ``ChiSquareTest``: draw many samples, histogram them
over a 2D parameterisation of their domain, integrate the claimed density over
every bin numerically, pool the bins whose expected count is too small, and
compute the p-value of Pearson's statistic. On failure the observed and
expected tables are printed, so a mismatch can be located.

A domain maps points (directions, disk points, ...) to two coordinates
``(x, y)`` in a rectangle and back, together with the Jacobian |dA / dx dy| of
the sample measure with respect to those coordinates. Samples that fall
outside the rectangle, or that the sampler marks as invalid (any NaN), are
counted in one extra "outside" cell whose expected probability is one minus
the integral of the density over the rectangle. So samplers that lose mass
(a BSDF reflecting below the horizon) are tested too.

The chi-square survival function uses the regularized upper incomplete gamma
function Q(k/2, x/2), evaluated by its power series for x < a + 1 and by a
Lentz continued fraction otherwise (Numerical Recipes, section 6.2); no scipy.
"""

import math

import numpy as np


# --- the chi-square distribution -------------------------------------------------

def _gamma_p_series(a, x):
    """Regularized lower incomplete gamma P(a, x) by its series (x < a + 1)."""
    term = 1.0 / a
    total = term
    ap = a
    for _ in range(10000):
        ap += 1.0
        term *= x / ap
        total += term
        if abs(term) < abs(total) * 1e-15:
            break
    return total * math.exp(-x + a * math.log(x) - math.lgamma(a))


def _gamma_q_fraction(a, x):
    """Regularized upper incomplete gamma Q(a, x) by a continued fraction (x >= a + 1)."""
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 10000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    return math.exp(-x + a * math.log(x) - math.lgamma(a)) * h


def gamma_q(a, x):
    """Regularized upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a)."""
    if x <= 0:
        return 1.0
    if x < a + 1.0:
        return max(0.0, 1.0 - _gamma_p_series(a, x))
    return _gamma_q_fraction(a, x)


def chi2_sf(stat, dof):
    """P(X >= stat) for X chi-square distributed with ``dof`` degrees of freedom."""
    return gamma_q(0.5 * dof, 0.5 * stat)


# --- pooled Pearson test on counts -----------------------------------------------

def pooled_chi2(observed, expected, min_expected=5.0):
    """Pearson's test of observed counts against expected counts (same shape).

    Cells with an expected count below ``min_expected`` are pooled into one cell
    (dropped if even the pool stays below it). A cell with observations but an
    expected count of zero fails at once (p = 0): samples outside the support.
    Returns (p_value, statistic, degrees of freedom, message).
    """
    obs = np.asarray(observed, np.float64).ravel()
    exp = np.asarray(expected, np.float64).ravel()
    impossible = (exp <= 0) & (obs > 0)
    if impossible.any():
        i = int(np.nonzero(impossible)[0][0])
        return 0.0, math.inf, 0, (f"{int(obs[impossible].sum())} samples in {int(impossible.sum())} "
                                  f"cell(s) of zero expected count (first: flat index {i})")
    small = exp < min_expected
    o_cells = list(obs[~small])
    e_cells = list(exp[~small])
    pooled_o, pooled_e = obs[small].sum(), exp[small].sum()
    note = ""
    if small.any():
        if pooled_e >= min_expected:
            o_cells.append(pooled_o)
            e_cells.append(pooled_e)
            note = f"pooled {int(small.sum())} small cells (expected {pooled_e:.1f}, observed {pooled_o:.0f})"
        else:
            note = (f"dropped {int(small.sum())} small cells (expected {pooled_e:.1f}, "
                    f"observed {pooled_o:.0f})")
    o_cells, e_cells = np.array(o_cells), np.array(e_cells)
    dof = len(o_cells) - 1
    if dof < 1:
        return 1.0, 0.0, 0, "fewer than two cells: nothing to test"
    stat = float(((o_cells - e_cells) ** 2 / e_cells).sum())
    return chi2_sf(stat, dof), stat, dof, note


# --- domains ------------------------------------------------------------------------

class Domain:
    """A rectangle of coordinates (x, y) covering a sample space.

    ``to_coords(points) -> (x, y)``, ``to_points(x, y) -> points`` and
    ``jacobian(x, y)`` (sample measure per unit dx dy) define it.
    """

    def __init__(self, bounds, to_coords, to_points, jacobian, name="domain"):
        self.bounds = np.asarray(bounds, np.float64)     # [[x0, x1], [y0, y1]]
        self.to_coords = to_coords
        self.to_points = to_points
        self.jacobian = jacobian
        self.name = name


def _frame(axis):
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    helper = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    t = np.cross(helper, a)
    t /= np.linalg.norm(t)
    return t, np.cross(a, t), a


def spherical_domain(axis=(0, 0, 1), cos_range=(-1.0, 1.0)):
    """Directions as (cos theta, phi) about ``axis``; solid angle = d(cos theta) d(phi)."""
    t, b, a = _frame(axis)

    def to_coords(w):
        w = np.asarray(w, np.float64)
        x, y, z = w @ t, w @ b, w @ a
        return z / np.sqrt(x * x + y * y + z * z), np.mod(np.arctan2(y, x), 2 * np.pi)

    def to_points(c, phi):
        s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
        return ((s * np.cos(phi))[:, None] * t + (s * np.sin(phi))[:, None] * b + c[:, None] * a)

    return Domain([cos_range, [0.0, 2 * np.pi]], to_coords, to_points,
                  lambda x, y: np.ones_like(x), "spherical (cos theta, phi)")


def log_spherical_domain(axis, eps=1e-9, max_angle=np.pi):
    """Directions as (log10(eps + 1 - cos theta), phi) about ``axis``, within
    ``max_angle`` of it: fine bins near the axis, for sharp lobes centred on it.
    The bins shrink down to angles of about sqrt(2 eps); directions beyond
    max_angle fall in the test's outside cell."""
    t, b, a = _frame(axis)
    ln10 = math.log(10.0)

    def to_coords(w):
        w = np.asarray(w, np.float64)
        x, y, z = w @ t, w @ b, w @ a
        theta = np.arctan2(np.sqrt(x * x + y * y), z)
        one_minus = 2.0 * np.sin(0.5 * theta) ** 2        # accurate near the axis
        return np.log10(eps + one_minus), np.mod(np.arctan2(y, x), 2 * np.pi)

    def to_points(lx, phi):
        c = 1.0 - (10.0 ** lx - eps)
        s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
        return ((s * np.cos(phi))[:, None] * t + (s * np.sin(phi))[:, None] * b + c[:, None] * a)

    top = math.log10(eps + 2.0 * math.sin(0.5 * max_angle) ** 2)
    return Domain([[math.log10(eps), top], [0.0, 2 * np.pi]], to_coords, to_points,
                  lambda lx, phi: ln10 * 10.0 ** lx, "log-spherical (log10(eps + 1 - cos theta), phi)")


def disk_domain():
    """Points (N, 2) of the unit disk as (r^2, phi); area = 1/2 d(r^2) d(phi)."""
    def to_coords(p):
        p = np.asarray(p, np.float64)
        return p[:, 0] ** 2 + p[:, 1] ** 2, np.mod(np.arctan2(p[:, 1], p[:, 0]), 2 * np.pi)

    def to_points(r2, phi):
        r = np.sqrt(r2)
        return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)

    return Domain([[0.0, 1.0], [0.0, 2 * np.pi]], to_coords, to_points,
                  lambda x, y: np.full_like(x, 0.5), "disk (r^2, phi)")


def triangle_domain():
    """Barycentrics (N, 2) = (b0, b1) with b0 + b1 <= 1 as (s, f) = (b0 + b1,
    b1 / (b0 + b1)); area db0 db1 = s ds df, so the triangle is the unit square."""
    def to_coords(b):
        b = np.asarray(b, np.float64)
        s = b[:, 0] + b[:, 1]
        return s, np.where(s > 0, b[:, 1] / np.where(s > 0, s, 1.0), 0.0)

    def to_points(s, f):
        return np.stack([s * (1.0 - f), s * f], axis=1)

    return Domain([[0.0, 1.0], [0.0, 1.0]], to_coords, to_points,
                  lambda s, f: s, "triangle (b0 + b1, b1 / (b0 + b1))")


def box_domain(bounds):
    """Points (N, 2) in an axis-aligned rectangle, as themselves."""
    return Domain(bounds, lambda p: (np.asarray(p, np.float64)[:, 0], np.asarray(p, np.float64)[:, 1]),
                  lambda x, y: np.stack([x, y], axis=1), lambda x, y: np.ones_like(x), "box")


# --- integrating a density over bins -----------------------------------------------

def integrate_bins(fn, domain, res, sub=4, levels=5, rtol=1e-4, atol=1e-6):
    """Integral of fn(points) over each of res = (nx, ny) bins of the domain:
    (nx, ny) for fn values (N,), (nx, ny, k) for values (N, k).

    Midpoint rule on sub x sub points per bin, refined by doubling wherever the
    estimate still changes by more than rtol (relative) and atol (absolute,
    as a fraction of the total), up to ``levels`` doublings.
    """
    nx, ny = res
    (x0, x1), (y0, y1) = domain.bounds
    hx, hy = (x1 - x0) / nx, (y1 - y0) / ny
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    ix, iy = ix.ravel(), iy.ravel()

    def estimate(cells, k):
        offs = (np.arange(k) + 0.5) / k
        ox, oy = np.meshgrid(offs, offs, indexing="ij")
        ox, oy = ox.ravel(), oy.ravel()
        out = np.zeros((len(cells), width))
        chunk = max(1, 400000 // (k * k))
        for s in range(0, len(cells), chunk):
            c = cells[s:s + chunk]
            x = (x0 + (ix[c][:, None] + ox[None, :]) * hx).ravel()
            y = (y0 + (iy[c][:, None] + oy[None, :]) * hy).ravel()
            v = np.asarray(fn(domain.to_points(x, y)), np.float64).reshape(len(x), -1)
            v = v * domain.jacobian(x, y)[:, None]
            v = np.where(np.isfinite(v), v, 0.0)
            out[s:s + len(c)] = v.reshape(len(c), k * k, width).mean(axis=1) * hx * hy
        return out

    probe = np.asarray(fn(domain.to_points(np.array([x0]), np.array([y0]))))
    width = int(np.prod(probe.shape[1:])) if probe.ndim > 1 else 1
    cells = np.arange(nx * ny)
    values = estimate(cells, sub)
    k = sub
    for _ in range(levels):
        k *= 2
        finer = estimate(cells, k)
        scale = np.maximum(np.abs(values.sum(axis=0)), 1e-300)
        unsettled = (np.abs(finer - values[cells]) > np.maximum(rtol * np.abs(finer), atol * scale)).any(axis=1)
        values[cells] = finer
        cells = cells[unsettled]
        if len(cells) == 0:
            break
    return values.reshape((nx, ny) if width == 1 and probe.ndim == 1 else (nx, ny, width))


def integrate(fn, domain, res=(32, 32), **kw):
    """Integral of fn over the whole domain rectangle (a float, or (k,) for vector fn)."""
    total = integrate_bins(fn, domain, res, **kw).sum(axis=(0, 1))
    return float(total) if np.ndim(total) == 0 else total


# --- the test ---------------------------------------------------------------------

class ChiSquareTest:
    """Sampler against density over a domain.

    sample_fn(n) -> points, with NaN rows for invalid samples (counted "outside").
    pdf_fn(points) -> density with respect to the domain's sample measure.
    alpha is the significance level of the whole family of ``test_count`` tests
    (Sidak correction), as in Mitsuba.
    """

    def __init__(self, sample_fn, pdf_fn, domain, res=(24, 24), sample_count=400_000,
                 min_expected=5.0, alpha=0.01, test_count=1, sub=4, levels=5):
        self.sample_fn, self.pdf_fn, self.domain = sample_fn, pdf_fn, domain
        self.res, self.sample_count = tuple(res), int(sample_count)
        self.min_expected, self.alpha, self.test_count = min_expected, alpha, test_count
        self.sub, self.levels = sub, levels
        self.observed = self.expected = None
        self.p_value, self.messages = None, []

    @staticmethod
    def _filler(dim):
        """A harmless stand-in for invalid rows (they are counted outside anyway)."""
        return np.eye(dim)[-1] if dim > 1 else np.zeros(1)

    def tabulate(self):
        nx, ny = self.res
        (x0, x1), (y0, y1) = self.domain.bounds
        pts = np.asarray(self.sample_fn(self.sample_count), np.float64)
        pts = pts.reshape(self.sample_count, -1)
        valid = np.isfinite(pts).all(axis=1)
        x, y = self.domain.to_coords(np.where(valid[:, None], pts, self._filler(pts.shape[1])))
        inside = valid & (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
        bx = np.clip(((x[inside] - x0) / (x1 - x0) * nx).astype(int), 0, nx - 1)
        by = np.clip(((y[inside] - y0) / (y1 - y0) * ny).astype(int), 0, ny - 1)
        self.observed = np.bincount(bx * ny + by, minlength=nx * ny).reshape(nx, ny).astype(np.float64)
        self.outside_observed = float((~inside).sum())
        mass = integrate_bins(self.pdf_fn, self.domain, self.res, self.sub, self.levels)
        self.integral = float(mass.sum())
        self.expected = mass * self.sample_count
        self.outside_expected = max(0.0, 1.0 - self.integral) * self.sample_count

    def run(self):
        if self.observed is None:
            self.tabulate()
        obs = np.append(self.observed.ravel(), self.outside_observed)
        exp = np.append(self.expected.ravel(), self.outside_expected)
        # A density that integrates to more than one cannot be a sampler's density.
        if self.integral > 1.0 + 1e-3:
            self.p_value = 0.0
            self.messages.append(f"density integrates to {self.integral:.6f} > 1")
        else:
            self.p_value, stat, dof, note = pooled_chi2(obs, exp, self.min_expected)
            self.messages.append(f"chi2 = {stat:.2f}, dof = {dof}, p = {self.p_value:.3g}; {note}")
        threshold = 1.0 - (1.0 - self.alpha) ** (1.0 / self.test_count)
        ok = self.p_value > threshold
        if not ok:
            print(self.report(threshold))
        return ok

    def report(self, threshold=None):
        np.set_printoptions(linewidth=200, precision=1, suppress=True, threshold=100000)
        lines = [f"Chi-square test over {self.domain.name}, {self.sample_count} samples, bins {self.res}",
                 f"density integral {self.integral:.6f}; outside: observed {self.outside_observed:.0f}, "
                 f"expected {self.outside_expected:.1f}"]
        lines += self.messages
        if threshold is not None:
            lines.append(f"rejected at p <= {threshold:.3g}")
        lines += ["observed (rows x, columns y):", str(self.observed),
                  "expected:", str(self.expected),
                  "(observed - expected) / sqrt(expected):",
                  str((self.observed - self.expected) / np.sqrt(np.maximum(self.expected, 1e-9)))]
        np.set_printoptions()
        return "\n".join(lines)
