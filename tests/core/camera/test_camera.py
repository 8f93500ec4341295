"""Blender's camera model in core.camera.projection: primary rays and projection are
inverse, the sensor fit, shift and clipping follow Blender, the pixel
filter samples Cycles' Blackman-Harris window, and depth of field is
Cycles' thin lens (its aperture sampled uniformly)."""

import itertools

import numpy as np
import pytest

from support.chi2 import ChiSquareTest, box_domain, integrate
from restir_gi.core import Camera
from restir_gi.core.camera.projection import (
    PixelFilter, aperture_points, crop, generate_rays, pixel_size, project, view_depth)
from support.scenes import look_at

SIZES = [(64, 48), (48, 64), (50, 50)]
FITS = ["AUTO", "HORIZONTAL", "VERTICAL"]
PROJECTIONS = ["PERSP", "ORTHO"]


def camera(projection="PERSP", fit="AUTO", shift=(0.0, 0.0), **kw):
    m = look_at((1.0, -6.0, 2.5), (0.2, 0.3, 0.8), up=(0.1, 0.0, 1.0))
    return Camera(to_world=m, projection=projection, sensor_fit=fit, lens=35.0, sensor_width=36.0,
                  sensor_height=20.0, ortho_scale=4.0, shift_x=shift[0], shift_y=shift[1],
                  clip_start=0.3, clip_end=80.0, **kw)


def axes(cam):
    m = np.asarray(cam.to_world, np.float64)
    a = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    return m[:3, 3], a[:, 0], a[:, 1], a[:, 2]      # position, right, up, back


@pytest.mark.parametrize("projection,fit,size,shift", list(itertools.product(
    PROJECTIONS, FITS, SIZES, [(0.0, 0.0), (0.13, -0.07)])))
def test01_rays_and_projection_are_inverse(projection, fit, size, shift, rng):
    w, h = size
    cam = camera(projection, fit, shift)
    xy = rng.uniform([-0.5 * w, -0.5 * h], [1.5 * w, 1.5 * h], (2000, 2)).astype(np.float32)
    o, d, tmax = generate_rays(cam, w, h, xy)
    assert o.dtype == d.dtype == tmax.dtype == np.float32
    assert np.allclose(np.linalg.norm(d, axis=1), 1, atol=1e-6)
    t = rng.uniform(0.0, 1.0, len(xy)) * tmax * 0.5
    pts = o.astype(np.float64) + d.astype(np.float64) * t[:, None]
    back, depth = project(cam, w, h, pts)
    assert (depth > 0).all()
    assert np.abs(back - xy).max() < 1e-3


def test02_centre_ray_looks_down_minus_z():
    for projection, (w, h) in itertools.product(PROJECTIONS, SIZES):
        cam = camera(projection)
        pos, right, up, back = axes(cam)
        o, d, _ = generate_rays(cam, w, h, np.float32([[w / 2, h / 2]]))
        assert np.allclose(d[0], -back, atol=1e-6)
        assert np.allclose(o[0], pos - back * cam.clip_start, atol=1e-5)
        # y = 0 is the bottom row, x = 0 the left column.
        _, d_low, _ = generate_rays(cam, w, h, np.float32([[w / 2, 0], [0, h / 2]]))
        if projection == "PERSP":
            assert d_low[0] @ up < 0 and d_low[1] @ right < 0


def test03_field_of_view_follows_the_sensor_fit():
    """The left edge (or bottom edge) ray leaves at atan(sensor / 2 / lens)."""
    for (w, h), fit in itertools.product(SIZES, FITS):
        cam = camera("PERSP", fit)
        _, right, up, back = axes(cam)
        horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and w >= h)
        sensor = cam.sensor_height if fit == "VERTICAL" else cam.sensor_width
        edge = np.float32([[0, h / 2]]) if horizontal else np.float32([[w / 2, 0]])
        _, d, _ = generate_rays(cam, w, h, edge)
        side = right if horizontal else up
        assert (d[0] @ side) / -(d[0] @ back) == pytest.approx(-0.5 * sensor / cam.lens, rel=1e-5)
        # Square pixels: the other axis has the same angular pixel pitch.
        size, view = pixel_size(cam, w, h)
        assert view == (w if horizontal else h)
        assert size == pytest.approx(sensor / cam.lens / view)


def test04_ortho_scale_spans_the_fitted_axis():
    for (w, h), fit in itertools.product(SIZES, FITS):
        cam = camera("ORTHO", fit)
        _, right, up, back = axes(cam)
        o, d, _ = generate_rays(cam, w, h, np.float32([[0, 0], [w, h]]))
        assert np.allclose(d, -back, atol=1e-6)
        span = o[1] - o[0]
        horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and w >= h)
        extent = span @ right if horizontal else span @ up
        assert extent == pytest.approx(cam.ortho_scale, rel=1e-5)
        assert (span @ right) / (span @ up) == pytest.approx(w / h, rel=1e-5)


@pytest.mark.parametrize("projection", PROJECTIONS)
def test05_shift_moves_the_optical_axis(projection):
    for (w, h), fit in itertools.product(SIZES, FITS):
        sx, sy = 0.13, -0.07
        cam = camera(projection, fit, (sx, sy))
        _, _, _, back = axes(cam)
        _, view = pixel_size(cam, w, h)
        o, d, _ = generate_rays(cam, w, h, np.float32([[w / 2 - sx * view, h / 2 - sy * view]]))
        assert np.allclose(d[0], -back, atol=1e-5)


@pytest.mark.parametrize("projection", PROJECTIONS)
def test06_clipping(projection, rng):
    w, h = 64, 48
    cam = camera(projection)
    xy = rng.uniform(0, [w, h], (500, 2)).astype(np.float32)
    o, d, tmax = generate_rays(cam, w, h, xy)
    assert np.allclose(view_depth(cam, o), cam.clip_start, rtol=1e-4)
    assert np.allclose(view_depth(cam, o.astype(np.float64) + d * tmax[:, None].astype(np.float64)),
                       cam.clip_end, rtol=1e-4)
    # Moving clip_start moves only the origins along the same rays.
    cam2 = camera(projection)
    cam2.clip_start = 2.0
    o2, d2, _ = generate_rays(cam2, w, h, xy)
    assert np.allclose(d2, d, atol=1e-6)
    assert np.allclose(view_depth(cam2, o2), 2.0, rtol=1e-4)
    along = np.einsum("ij,ij->i", o2 - o, d)
    assert (along > 0).all()
    assert np.allclose(o + d * along[:, None], o2, atol=1e-4)


def test07_scaled_camera_matrix_gives_the_same_rays(rng):
    cam = camera()
    scaled = camera()
    scaled.to_world = cam.to_world.copy()
    scaled.to_world[:3, :3] *= np.float32([2.0, 0.5, 3.0])
    xy = rng.uniform(0, 64, (100, 2)).astype(np.float32)
    for a, b in zip(generate_rays(cam, 64, 64, xy), generate_rays(scaled, 64, 64, xy)):
        assert np.allclose(a, b, atol=1e-5)


def test08_points_behind_a_perspective_camera_have_negative_depth():
    cam = camera()
    pos, _, _, back = axes(cam)
    _, depth = project(cam, 64, 64, np.array([pos + 2 * back, pos - 2 * back]))
    assert depth[0] < 0 < depth[1]


# --- pixel filter -------------------------------------------------------------------------

def blackman_harris(x):
    """Cycles' window over [0, 1]."""
    a = 2 * np.pi * x
    return 0.35875 - 0.48829 * np.cos(a) + 0.14128 * np.cos(2 * a) - 0.01168 * np.cos(3 * a)


def filter_pdf(width):
    """Density of one offset: Blackman-Harris over [-width, width], normalised
    (its mean over [0, 1] is 0.35875)."""
    return lambda x: np.where(np.abs(x) <= width, blackman_harris(x / (2 * width) + 0.5), 0.0) / (
        0.35875 * 2 * width)


@pytest.mark.parametrize("width", [1.5, 0.7, 3.0])
def test09_pixel_filter_is_blackman_harris(width, rng):
    f = PixelFilter(width)
    u = rng.random((400_000, 2), dtype=np.float32)
    off = f.offsets(u)
    assert np.abs(off).max() <= width + 1e-6
    assert np.abs(off.mean(axis=0)).max() < 0.01 * width           # symmetric about the centre
    pdf1 = filter_pdf(width)
    pdf2 = lambda p: pdf1(p[:, 0]) * pdf1(p[:, 1])  # noqa: E731
    dom = box_domain([[-width, width], [-width, width]])
    assert integrate(pdf2, dom, res=(24, 24)) == pytest.approx(1.0, abs=1e-4)
    # Separable and Blackman-Harris in both axes: a 2D test over the whole support.
    assert ChiSquareTest(lambda n: off, pdf2, dom, res=(24, 24), sample_count=len(off), test_count=3).run()
    # Finer bins along x alone (symmetry and the shape near the edges).
    pts = np.stack([off[:, 0], np.zeros(len(off))], axis=1)
    dom1 = box_domain([[-width, width], [-1, 1]])
    assert ChiSquareTest(lambda n: pts, lambda p: pdf1(p[:, 0]) * 0.5, dom1, res=(64, 1),
                         sample_count=len(off), test_count=3).run()


def test10_zero_width_filter_samples_the_pixel_centre(rng):
    u = rng.random((100, 2), dtype=np.float32)
    assert (PixelFilter(0.0).offsets(u) == 0).all()


# --- depth of field -------------------------------------------------------------------

@pytest.mark.parametrize("projection", PROJECTIONS)
def test11_lens_rays_meet_on_the_focus_plane(projection, rng):
    """All lens samples of one film position pass through the point the
    pinhole ray sees on the plane focus_distance along the view axis; their
    origins spread over the aperture around the pinhole's."""
    cam = camera(projection, aperture_size=0.2, focus_distance=5.0)
    n = 2000
    xy = np.tile(np.array([[17.3, 29.8]], np.float32), (n, 1))
    o0, d0, _ = generate_rays(cam, 64, 48, xy[:1])
    o, d, _ = generate_rays(cam, 64, 48, xy, rng.random((n, 2), dtype=np.float32))
    pos, _, _, back = axes(cam)

    def on_focus_plane(o, d):      # where the rays cross the plane 5 in front of the camera
        t = (5.0 - (-(o - pos) @ back)) / (-(d @ back))
        return o + d * t[:, None]
    pinhole = on_focus_plane(o0.astype(np.float64), d0.astype(np.float64))[0]
    hits = on_focus_plane(o.astype(np.float64), d.astype(np.float64))
    assert np.abs(hits - pinhole).max() < 1e-3
    assert np.linalg.norm(d, axis=1) == pytest.approx(1.0, abs=1e-5)
    # Origins (moved to the clip plane along their rays) spread over the
    # aperture's radius around the pinhole origin, centred on it.
    spread = np.linalg.norm(o - o0, axis=1)
    assert spread.max() <= 0.2 * 1.05 and spread.max() > 0.2 * 0.9
    assert np.abs((o - o0).mean(axis=0)).max() < 0.01
    # Without lens uniforms, or without an aperture: the pinhole rays.
    pin, _, _ = generate_rays(camera(projection), 64, 48, xy[:5], rng.random((5, 2), dtype=np.float32))
    assert np.allclose(pin, generate_rays(cam, 64, 48, xy[:5])[0])


@pytest.mark.parametrize("blades, ratio", [(0, 1.0), (5, 1.0), (6, 2.0)])
def test12_aperture_is_uniform_over_its_shape(blades, ratio, rng):
    """Uniform over a disk or a regular polygon inscribed in the aperture
    radius (the middle of a side at the rotation angle, as Cycles), x
    divided by the ratio."""
    cam = Camera(aperture_size=0.5, aperture_blades=blades, aperture_rotation=0.3, aperture_ratio=ratio)
    u = rng.random((400_000, 2), dtype=np.float32)
    p = aperture_points(cam, u)
    q = p / 0.5
    q[:, 0] *= ratio        # back to the unit shape

    def inside(q):
        if blades == 0:
            return np.hypot(q[:, 0], q[:, 1]) <= 1.0
        half = np.pi / blades
        a = np.arctan2(q[:, 1], q[:, 0]) - 0.3 + half
        local = np.mod(a, 2 * half) - half    # angle from the middle of a side
        return np.hypot(q[:, 0], q[:, 1]) * np.cos(local) <= np.cos(half)
    area = np.pi if blades == 0 else 0.5 * blades * np.sin(2 * np.pi / blades)
    assert inside(q).mean() > 0.9999
    pdf = lambda x: np.where(inside(x), 1.0 / area, 0.0)  # noqa: E731
    dom = box_domain([[-1, 1], [-1, 1]])
    assert ChiSquareTest(lambda n: q.astype(np.float64), pdf, dom, res=(24, 24), sample_count=len(q), sub=16).run()
    if blades:      # the corners are there: the polygon is inscribed in the radius
        corner = np.array([np.cos(0.3 + np.pi / blades), np.sin(0.3 + np.pi / blades)])
        assert np.linalg.norm(q - corner, axis=1).min() < 0.02


@pytest.mark.parametrize("projection, fit", [("PERSP", "AUTO"), ("PERSP", "VERTICAL"), ("ORTHO", "AUTO")])
def test13_cropped_camera_images_its_rectangle(projection, fit, rng):
    """A render region: the cropped camera's pixel (x, y) is the full image's
    pixel (x0 + x, y0 + y), rays and projection alike."""
    cam = camera(projection, fit, shift=(0.05, -0.1))
    x0, y0, w, h = 10, 31, 23, 9
    part = crop(cam, 64, 48, x0, y0, w, h)
    xy = rng.random((50, 2)).astype(np.float32) * [w, h]
    o, d, t = generate_rays(part, w, h, xy)
    o2, d2, t2 = generate_rays(cam, 64, 48, xy + np.array([x0, y0], np.float32))
    assert np.allclose(o, o2, atol=1e-4) and np.allclose(d, d2, atol=1e-5) and np.allclose(t, t2, rtol=1e-5)
    film, _ = project(part, w, h, o2 + 3.0 * d2)
    assert np.allclose(film, xy, atol=1e-3)
