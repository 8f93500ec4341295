"""Cycles' panoramic cameras: equirectangular, fisheye (equidistant,
equisolid, lens polynomial), mirror ball, central cylindrical and
equiangular cube map face film positions to directions and back.

As in Cycles, a panoramic camera maps the film to [0, 1]^2 (u right, v up;
shift moves that window) and looks along +x of its own panorama frame, +z up
(so an equirectangular camera pointed along world +x sees the middle of an
environment texture with default mapping); in Blender's camera frame that
direction is -z, and panorama +y is camera -x. The mirror ball has a frame
of its own: it looks along -y, +z up, +x right. Film positions outside a
fisheye's circle get no ray: ``directions`` marks them, and the camera
passes render them black (Cycles traces nothing there).

Depth for panoramic cameras is the distance from the camera (Cycles'
camera_z_depth), not the distance along the view axis.
"""

import numpy as np

PANO = "PANO"
TYPES = ("EQUIRECTANGULAR", "FISHEYE_EQUIDISTANT", "FISHEYE_EQUISOLID", "FISHEYE_LENS_POLYNOMIAL",
         "MIRRORBALL", "CENTRAL_CYLINDRICAL", "EQUIANGULAR_CUBEMAP_FACE")
SENSOR_FIT = ("FISHEYE_EQUISOLID", "FISHEYE_LENS_POLYNOMIAL")     # types that read the sensor


def is_panorama(camera):
    return getattr(camera, "projection", "PERSP") == PANO


def _full_size(camera, width, height):
    """(x0, y0, W, H): where a width x height film lies in the full image
    (a render region's camera carries its place, core.camera.projection.crop)."""
    region = getattr(camera, "pano_region", None)
    if region is None:
        return 0.0, 0.0, float(width), float(height)
    return tuple(float(v) for v in region)


def sensor_size(camera, W, H):
    """(width, height) of the sensor in mm as Cycles fits it for equisolid
    fisheyes: the fitted axis is the sensor's, the other follows the image's
    aspect (AUTO fits the wider axis; a square image fits vertically)."""
    fit = camera.sensor_fit
    horizontal = (W > H) if fit == "AUTO" else fit == "HORIZONTAL"
    size = camera.sensor_width if fit in ("AUTO", "HORIZONTAL") else camera.sensor_height
    if horizontal:
        return size, size * H / W
    return size * W / H, size


def film_to_uv(camera, width, height, xy):
    x0, y0, W, H = _full_size(camera, width, height)
    u = (x0 + np.asarray(xy[:, 0], np.float64)) / W + camera.shift_x
    v = (y0 + np.asarray(xy[:, 1], np.float64)) / H + camera.shift_y
    return u, v


def uv_to_film(camera, width, height, u, v):
    x0, y0, W, H = _full_size(camera, width, height)
    return (u - camera.shift_x) * W - x0, (v - camera.shift_y) * H - y0


def _polar_to_dir(r_norm_x, r_norm_y, theta):
    """Panorama-frame directions at angle theta from +x, around it along the
    film's (x, y) direction (r_norm_x, r_norm_y), as Cycles' fisheyes:
    film right is panorama -y, film up panorama +z."""
    r = np.hypot(r_norm_x, r_norm_y)
    safe = np.where(r > 0, r, 1.0)
    cx, sy = np.where(r > 0, r_norm_x / safe, 1.0), np.where(r > 0, r_norm_y / safe, 0.0)
    st = np.sin(theta)
    return np.stack([np.cos(theta), -cx * st, sy * st], axis=1)


def local_directions(camera, width, height, xy):
    """(N, 3) unit directions in the panorama frame for film positions xy
    (N, 2) in pixels, and (N,) bool: inside the lens."""
    u, v = film_to_uv(camera, width, height, xy)
    kind = camera.panorama_type
    if kind in _OTHER_TO_DIR:
        return _OTHER_TO_DIR[kind](camera, width, height, u, v)
    if kind == "FISHEYE_EQUIDISTANT":
        a, b = 2.0 * (u - 0.5), 2.0 * (v - 0.5)
        r = np.hypot(a, b)
        return _polar_to_dir(a, b, r * camera.fisheye_fov * 0.5), r <= 1.0
    if kind == "FISHEYE_EQUISOLID":
        x0, y0, W, H = _full_size(camera, width, height)
        sw, sh = sensor_size(camera, W, H)
        a, b = (u - 0.5) * sw, (v - 0.5) * sh
        r = np.hypot(a, b)
        lens = max(float(camera.fisheye_lens), 1e-6)
        rmax = 2.0 * lens * np.sin(min(float(camera.fisheye_fov), 2.0 * np.pi) * 0.25)
        theta = 2.0 * np.arcsin(np.clip(r / (2.0 * lens), 0.0, 1.0))
        return _polar_to_dir(a, b, theta), r <= rmax
    # Equirectangular over the latitude and longitude ranges.
    phi = (camera.longitude_min - camera.longitude_max) * u - camera.longitude_min
    theta = (camera.latitude_min - camera.latitude_max) * v - camera.latitude_min + 0.5 * np.pi
    st = np.sin(theta)
    d = np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=1)
    return d, np.ones(len(u), bool)


def local_to_film(camera, width, height, d):
    """Film positions (N, 2) of panorama-frame directions d (N, 3) (any
    length; zero rows go to the film's centre): the inverse of
    local_directions, also for directions outside the lens."""
    d = np.asarray(d, np.float64)
    length = np.linalg.norm(d, axis=1)
    d = d / np.where(length > 0, length, 1.0)[:, None]
    d[length == 0] = (1.0, 0.0, 0.0)
    kind = camera.panorama_type
    theta = np.arccos(np.clip(d[:, 0], -1.0, 1.0))
    phi = np.arctan2(d[:, 2], -d[:, 1])
    if kind in _OTHER_TO_UV:
        u, v = _OTHER_TO_UV[kind](camera, width, height, d, theta, phi)
    elif kind == "FISHEYE_EQUIDISTANT":
        r = theta / max(float(camera.fisheye_fov), 1e-6)
        u, v = 0.5 + r * np.cos(phi), 0.5 + r * np.sin(phi)
    elif kind == "FISHEYE_EQUISOLID":
        x0, y0, W, H = _full_size(camera, width, height)
        sw, sh = sensor_size(camera, W, H)
        r = 2.0 * float(camera.fisheye_lens) * np.sin(0.5 * theta)
        u, v = 0.5 + r * np.cos(phi) / sw, 0.5 + r * np.sin(phi) / sh
    else:
        span_u = camera.longitude_min - camera.longitude_max
        span_v = camera.latitude_min - camera.latitude_max
        u = (np.arctan2(d[:, 1], d[:, 0]) + camera.longitude_min) / (span_u if span_u else -1e-6)
        v = (np.arccos(np.clip(d[:, 2], -1.0, 1.0)) + camera.latitude_min - 0.5 * np.pi) \
            / (span_v if span_v else -1e-6)
    fx, fy = uv_to_film(camera, width, height, u, v)
    return np.stack([fx, fy], axis=1)


def _polynomial(camera, r):
    k = [float(getattr(camera, f"fisheye_polynomial_k{i}", 0.0)) for i in range(5)]
    return -(k[0] + k[1] * r + k[2] * r ** 2 + k[3] * r ** 3 + k[4] * r ** 4)


def _lens_polynomial(camera, width, height, u, v):
    x0, y0, W, H = _full_size(camera, width, height)
    sw, sh = sensor_size(camera, W, H)
    a, b = (u - 0.5) * sw, (v - 0.5) * sh
    theta = _polynomial(camera, np.hypot(a, b))
    inside = np.abs(theta) <= 0.5 * float(camera.fisheye_fov)
    return _polar_to_dir(a, b, theta), inside


def _lens_polynomial_uv(camera, width, height, d, theta, phi):
    """Newton's method on the polynomial, from its linear term's solution."""
    x0, y0, W, H = _full_size(camera, width, height)
    sw, sh = sensor_size(camera, W, H)
    k1 = float(getattr(camera, "fisheye_polynomial_k1", 0.0)) or -1e-6
    target = -theta
    r = (target - float(getattr(camera, "fisheye_polynomial_k0", 0.0))) / k1
    for _ in range(20):
        f = -_polynomial(camera, r) - target
        h = 1e-4 * np.maximum(np.abs(r), 1.0)
        df = (-_polynomial(camera, r + h) + _polynomial(camera, r - h)) / (2 * h)
        r = r - f / np.where(np.abs(df) > 1e-12, df, 1e-12)
    r = np.where(np.isfinite(r), r, 0.0)
    return 0.5 + r * np.cos(phi) / sw, 0.5 + r * np.sin(phi) / sh


def _mirrorball(camera, width, height, u, v):
    x, z = 2.0 * u - 1.0, 2.0 * v - 1.0
    inside = x * x + z * z <= 1.0
    n = np.stack([x, -np.sqrt(np.maximum(1.0 - x * x - z * z, 0.0)), z], axis=1)
    i = np.array([0.0, -1.0, 0.0])
    return 2.0 * (n @ i)[:, None] * n - i, inside        # the view reflected in the ball


def _mirrorball_uv(camera, width, height, d, theta, phi):
    d = np.array(d)
    d[:, 1] -= 1.0
    div = 2.0 * np.sqrt(np.maximum(-0.5 * d[:, 1], 0.0))
    d /= np.where(div > 0, div, 1.0)[:, None]
    return 0.5 * (d[:, 0] + 1.0), 0.5 * (d[:, 2] + 1.0)


def _cylinder_range(camera):
    radius = float(getattr(camera, "central_cylindrical_radius", 1.0)) or 1e-6
    return (-float(camera.central_cylindrical_range_u_min), -float(camera.central_cylindrical_range_u_max),
            float(camera.central_cylindrical_range_v_min) / radius,
            float(camera.central_cylindrical_range_v_max) / radius)


def _central_cylindrical(camera, width, height, u, v):
    a0, a1, z0, z1 = _cylinder_range(camera)
    theta = a0 + (a1 - a0) * u
    d = np.stack([np.cos(theta), np.sin(theta), z0 + (z1 - z0) * v], axis=1)
    return d / np.linalg.norm(d, axis=1, keepdims=True), np.ones(len(u), bool)


def _central_cylindrical_uv(camera, width, height, d, theta, phi):
    a0, a1, z0, z1 = _cylinder_range(camera)
    z = d[:, 2] / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
    angle = np.arctan2(d[:, 1], d[:, 0])
    return (angle - a0) / ((a1 - a0) or 1e-6), (z - z0) / ((z1 - z0) or 1e-6)


def _cubemap_face(camera, width, height, u, v):
    d = np.stack([np.ones(len(u)), np.tan((0.5 - u) * 0.5 * np.pi), np.tan((v - 0.5) * 0.5 * np.pi)], axis=1)
    return d / np.linalg.norm(d, axis=1, keepdims=True), np.ones(len(u), bool)


def _cubemap_face_uv(camera, width, height, d, theta, phi):
    return 0.5 - np.arctan2(d[:, 1], d[:, 0]) * 2.0 / np.pi, np.arctan2(d[:, 2], d[:, 0]) * 2.0 / np.pi + 0.5


_OTHER_TO_DIR = {"FISHEYE_LENS_POLYNOMIAL": _lens_polynomial, "MIRRORBALL": _mirrorball,
                 "CENTRAL_CYLINDRICAL": _central_cylindrical, "EQUIANGULAR_CUBEMAP_FACE": _cubemap_face}
_OTHER_TO_UV = {"FISHEYE_LENS_POLYNOMIAL": _lens_polynomial_uv, "MIRRORBALL": _mirrorball_uv,
                "CENTRAL_CYLINDRICAL": _central_cylindrical_uv, "EQUIANGULAR_CUBEMAP_FACE": _cubemap_face_uv}


# Panorama frame <-> Blender's camera frame (x right, y up, looking down -z):
# panorama +x is camera -z, +y is camera -x, +z is camera +y; the mirror
# ball's x, y, z are the camera's x, z, y.
def to_camera_frame(d, kind=None):
    if kind == "MIRRORBALL":
        return np.stack([d[:, 0], d[:, 2], d[:, 1]], axis=1)
    return np.stack([-d[:, 1], d[:, 2], -d[:, 0]], axis=1)


def from_camera_frame(c, kind=None):
    if kind == "MIRRORBALL":
        return np.stack([c[:, 0], c[:, 2], c[:, 1]], axis=1)
    return np.stack([-c[:, 2], -c[:, 0], c[:, 1]], axis=1)
