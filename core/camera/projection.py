"""Blender's camera model: primary rays for whole images, and projection back.

Follows Blender's view plane: the sensor is fitted to one image axis (AUTO
picks the larger one), shift is in units of that axis, perspective cameras
clip along the view axis between clip_start and clip_end. Pixel (x, y) has
y = 0 at the bottom row, as Blender's render result stores it.
"""

from dataclasses import replace

import numpy as np

from . import panorama
from .motion import rigid_at
from ..util.rows import matmul3
from ..sampling.warps import Distribution1D, square_to_concentric_disk


def _fit(camera, width, height):
    """(size of the fitted sensor axis, number of pixels along it)."""
    fit = camera.sensor_fit
    if fit == "AUTO":
        return camera.sensor_width, float(max(width, height))
    if fit == "HORIZONTAL":
        return camera.sensor_width, float(width)
    return camera.sensor_height, float(height)


def camera_frame(camera):
    """Camera position and orthonormal axes (right, up, back) in world space."""
    m = np.asarray(camera.to_world, dtype=np.float64)
    axes = m[:3, :3]
    norms = np.linalg.norm(axes, axis=0)
    axes = axes / np.where(norms > 0, norms, 1)
    return m[:3, 3], axes


def camera_space_normals(camera, normals):
    """(N, 3) float32 world-space normals (N, 3) in Cycles' camera space, as
    its Denoising Normal pass holds them: x right, y up, z along the view
    direction (a normal facing the camera is (0, 0, -1)); zero rows stay zero."""
    _, axes = camera_frame(camera)
    m = (axes * np.array([1.0, 1.0, -1.0])).astype(np.float32)     # columns: right, up, forward
    return matmul3(np.asarray(normals, np.float32).reshape(-1, 3), m).astype(np.float32) + np.float32(0)


def pixel_size(camera, width, height):
    """Size of one pixel on the image plane at unit distance (persp) or in world units (ortho)."""
    sensor, view = _fit(camera, width, height)
    if camera.projection == "ORTHO":
        return camera.ortho_scale / view, view
    return sensor / max(camera.lens, 1e-6) / view, view


def aperture_points(camera, u):
    """(N, 2) points on the lens (camera x, y in scene units) for uniforms u
    (N, 2): uniform over a disk of radius aperture_size, or over a regular
    polygon of ``aperture_blades`` corners inscribed in it, the middle of one
    side at angle aperture_rotation (Cycles' orientation), x divided by
    aperture_ratio (anamorphic bokeh)."""
    blades = int(camera.aperture_blades)
    if blades < 3:
        p = square_to_concentric_disk(u).astype(np.float64)
    else:
        # A triangle between the centre and two neighbouring corners, then a
        # uniform point in it.
        k = np.minimum((u[:, 0] * blades).astype(np.int64), blades - 1)
        v = u[:, 0] * blades - k            # reused: uniform in [0, 1) within the triangle's pick
        step = 2.0 * np.pi / blades
        a0 = camera.aperture_rotation + (k - 0.5) * step
        c0 = np.stack([np.cos(a0), np.sin(a0)], axis=1)
        c1 = np.stack([np.cos(a0 + step), np.sin(a0 + step)], axis=1)
        s = np.sqrt(u[:, 1])[:, None]
        p = s * ((1.0 - v)[:, None] * c0 + v[:, None] * c1)
    p = p * camera.aperture_size
    p[:, 0] /= max(float(camera.aperture_ratio), 1e-6)
    return p


def crop(camera, width, height, x0, y0, w, h):
    """The camera that images the rectangle of pixels [x0, x0 + w) x [y0, y0 + h)
    of a width x height image as a w x h image of its own (a render region):
    the same pixel size, the sensor fitted to the new width, the shift moved
    to the rectangle's centre."""
    w, h = max(1, int(w)), max(1, int(h))
    if panorama.is_panorama(camera):
        fx, fy, full_w, full_h = panorama._full_size(camera, width, height)
        return replace(camera, pano_region=(fx + x0, fy + y0, full_w, full_h))
    size, view = pixel_size(camera, width, height)
    sx = (x0 + 0.5 * w - 0.5 * width) / w + camera.shift_x * view / w
    sy = (y0 + 0.5 * h - 0.5 * height) / w + camera.shift_y * view / w
    if camera.projection == "ORTHO":
        return replace(camera, sensor_fit="HORIZONTAL", ortho_scale=size * w, shift_x=sx, shift_y=sy)
    return replace(camera, sensor_fit="HORIZONTAL", sensor_width=size * w * max(camera.lens, 1e-6),
                   shift_x=sx, shift_y=sy)


def generate_rays(camera, width, height, pixel_xy, lens_u=None, time_u=None):
    """Rays through film positions pixel_xy (N, 2) in pixel units (x + 0.5 is a centre).

    lens_u: (N, 2) uniforms for the lens position when the camera has depth
    of field (aperture_size > 0); None traces through the lens centre (a
    pinhole). Rays of one film position meet on the plane focus_distance
    along the view axis, as in Cycles' thin lens.

    Returns origins, unit directions and tmax (clip_end), origins already moved
    to clip_start along the ray. A panoramic camera's film positions outside
    its lens get tmax 0 (no ray: Accel reports a miss, the camera passes
    leave them black).

    time_u: (N,) uniforms for each ray's time over the shutter when the
    camera moves (camera.motion); None renders the frame's camera.
    """
    if time_u is not None and getattr(camera, "motion", None) is not None:
        return _moving_rays(camera, width, height, pixel_xy, lens_u, time_u)
    if panorama.is_panorama(camera):
        return _panorama_rays(camera, width, height, pixel_xy, lens_u)
    size, view = pixel_size(camera, width, height)
    pos, axes = camera_frame(camera)
    x = (pixel_xy[:, 0] - 0.5 * width + camera.shift_x * view) * size
    y = (pixel_xy[:, 1] - 0.5 * height + camera.shift_y * view) * size
    n = len(pixel_xy)
    lens = None
    if lens_u is not None and camera.aperture_size > 0:
        lens = aperture_points(camera, lens_u)
    focus = max(float(camera.focus_distance), 1e-5)
    if camera.projection == "ORTHO":
        local_o = np.stack([x, y, np.full(n, -camera.clip_start)], axis=1)
        local_d = np.broadcast_to(np.array([0.0, 0.0, -1.0]), (n, 3))
        if lens is not None:
            # From a point on the lens towards the film position's point on
            # the focus plane, then to the clip plane along the ray.
            local_d = np.stack([-lens[:, 0], -lens[:, 1], np.full(n, -focus)], axis=1)
            local_d /= np.linalg.norm(local_d, axis=1)[:, None]
            local_o[:, :2] += lens
            local_o += local_d * (camera.clip_start / -local_d[:, 2])[:, None]
            local_o[:, 2] = -camera.clip_start
        origins = pos + matmul3(local_o, axes.T)
        d = matmul3(np.ascontiguousarray(local_d), axes.T)
        tmax = np.full(n, camera.clip_end - camera.clip_start)
    else:
        local_d = np.stack([x, y, -np.ones(n)], axis=1)
        length = np.sqrt(x * x + y * y + 1.0)
        if lens is None:
            d = matmul3(local_d, axes.T) / length[:, None]
            origins = pos + d * (camera.clip_start * length)[:, None]
        else:
            target = local_d * focus
            target[:, :2] -= lens
            target /= np.linalg.norm(target, axis=1)[:, None]
            d = matmul3(target, axes.T)
            origins = pos + matmul3(np.stack([lens[:, 0], lens[:, 1], np.zeros(n)], axis=1), axes.T)
            # Clipped as Cycles does: clip_start over the pinhole ray's cosine.
            origins = origins + d * (camera.clip_start * length)[:, None]
        tmax = (camera.clip_end - camera.clip_start) * length
    return (origins.astype(np.float32), np.ascontiguousarray(d, dtype=np.float32),
            np.maximum(tmax, 1e-6).astype(np.float32))


def _moving_rays(camera, width, height, pixel_xy, lens_u, time_u):
    """generate_rays of a camera that moves over the shutter: the rays in its
    own frame, then each moved by the camera at its time."""
    still = replace(camera, to_world=np.eye(4, dtype=np.float32), motion=None)
    o, d, tmax = generate_rays(still, width, height, pixel_xy, lens_u)
    r, t = rigid_at(camera.motion, time_u)
    o = np.einsum("nij,nj->ni", r, o.astype(np.float64)) + t
    d = np.einsum("nij,nj->ni", r, d.astype(np.float64))
    return o.astype(np.float32), np.ascontiguousarray(d, dtype=np.float32), tmax


def _panorama_rays(camera, width, height, pixel_xy, lens_u=None):
    """generate_rays of a panoramic camera. Depth of field as Cycles does it
    for panoramas: the lens point in the plane across each pinhole ray,
    aimed at the point focus_distance along it."""
    pos, axes = camera_frame(camera)
    local, inside = panorama.local_directions(camera, width, height, np.asarray(pixel_xy, np.float64))
    local[~inside] = (1.0, 0.0, 0.0)
    start = np.zeros_like(local)
    if lens_u is not None and camera.aperture_size > 0:
        lens = aperture_points(camera, lens_u)
        u_axis = np.array([1.0, 0.0, 0.0]) - local[:, :1] * local
        length = np.linalg.norm(u_axis, axis=1, keepdims=True)
        u_axis = np.where(length > 1e-9, u_axis / np.maximum(length, 1e-30), np.array([0.0, 1.0, 0.0]))
        v_axis = np.cross(local, u_axis)
        start = u_axis * lens[:, :1] + v_axis * lens[:, 1:2]
        aim = local * max(float(camera.focus_distance), 1e-5) - start
        local = aim / np.maximum(np.linalg.norm(aim, axis=1, keepdims=True), 1e-30)
    kind = camera.panorama_type
    d = matmul3(panorama.to_camera_frame(local, kind), axes.T)
    d /= np.maximum(np.linalg.norm(d, axis=1), 1e-30)[:, None]
    origins = pos + matmul3(panorama.to_camera_frame(start, kind), axes.T) + d * camera.clip_start
    tmax = np.where(inside, max(camera.clip_end - camera.clip_start, 1e-6), 0.0)
    return (origins.astype(np.float32), np.ascontiguousarray(d, dtype=np.float32), tmax.astype(np.float32))


def project(camera, width, height, points):
    """World points (N, 3) to film positions (N, 2) in pixels and view depth (N,).
    Points behind a perspective camera get depth <= 0. Panoramic cameras:
    the depth is the distance (view_depth), the film position that of the
    direction, inside the lens or not."""
    if panorama.is_panorama(camera):
        pos, axes = camera_frame(camera)
        local = matmul3(np.asarray(points, np.float64) - pos, axes)
        film = panorama.local_to_film(camera, width, height, panorama.from_camera_frame(local, camera.panorama_type))
        return film.astype(np.float32), np.linalg.norm(local, axis=1).astype(np.float32)
    size, view = pixel_size(camera, width, height)
    pos, axes = camera_frame(camera)
    local = matmul3(np.asarray(points, np.float64) - pos, axes)
    depth = -local[:, 2]
    if camera.projection == "ORTHO":
        px, py = local[:, 0], local[:, 1]
    else:
        safe = np.where(depth > 1e-12, depth, 1e-12)
        px, py = local[:, 0] / safe, local[:, 1] / safe
    fx = px / size + 0.5 * width - camera.shift_x * view
    fy = py / size + 0.5 * height - camera.shift_y * view
    return np.stack([fx, fy], axis=1).astype(np.float32), depth.astype(np.float32)


def view_depth(camera, points):
    """Distance along the camera's view axis (Blender's Z/Depth pass); the
    distance from the camera for panoramic cameras, as Cycles."""
    pos, axes = camera_frame(camera)
    if panorama.is_panorama(camera):
        return np.linalg.norm(np.asarray(points, np.float64) - pos, axis=1).astype(np.float32)
    return -matmul3(np.asarray(points, np.float64) - pos, axes[:, 2]).astype(np.float32)


class PixelFilter:
    """Importance sampling of Cycles' Blackman-Harris pixel filter, separably in x
    and y, so every sample has weight one (filter importance sampling).

    As in Cycles, a filter width w spans [-w, w] pixels (the window is twice
    the user-facing width)."""

    def __init__(self, width=1.5, bins=256):
        self.width = 2.0 * float(width)
        if self.width <= 0:
            self.dist = None
            return
        x = (np.arange(bins) + 0.5) / bins  # in [0, 1] across the filter support
        a = 2.0 * np.pi * x
        w = 0.35875 - 0.48829 * np.cos(a) + 0.14128 * np.cos(2 * a) - 0.01168 * np.cos(3 * a)
        self.dist = Distribution1D(np.maximum(w, 0.0))

    def offsets(self, u):
        """(N, 2) offsets from the pixel centre for uniforms u (N, 2)."""
        if self.dist is None:
            return np.zeros_like(u)
        x = self.dist.sample_point(u[:, 0])
        y = self.dist.sample_point(u[:, 1])
        return (np.stack([x, y], axis=1) - 0.5) * self.width
