"""Measure Cycles' radiometric conventions and compare them with closed-form predictions.

Run from the repository root:

    .venv/bin/python bench/cycles_conventions.py

Every case builds a tiny scene in code (numpy + foreach_set meshes, an orthographic
camera, one emitter), renders it with Cycles on the CPU (2 fixed threads, no
denoising, no adaptive sampling, max_bounces 0 unless stated; the scenes and the
render are in bench/cycles_scene.py), reads the 32-bit linear EXR back and compares
the image mean with the prediction of the formulas in docs/cycles-conventions.md.
A diffuse receiver of albedo a shows a / pi * E, where E is the irradiance.
Prints: case, predicted, measured, measured / predicted.
"""

import math
import shutil
import sys
import time

import numpy as np
import bpy

from cycles_scene import (ALBEDO, RES, SPP, TMP, add_camera, add_light, add_quad, make_world, material,
                          new_scene, pixel_centres, receiver, render)


# --------------------------------------------------------------------------- formulas


def point_intensity(power, color=(1.0, 1.0, 1.0), exposure=0.0):
    """Radiant intensity [W/sr] of a point/spot light: I = P * C * 2^exposure / (4 pi)."""
    return np.asarray(color) * power * 2.0 ** exposure / (4.0 * math.pi)


def point_irradiance(I, h, radius=0.0, soft_falloff=True, mask=None):  # noqa: E741 (the formula's I)
    """Mean irradiance over the camera patch on the z = 0 plane from a light at height h.

    soft falloff on (default): the light is a disk of radius r facing the receiver,
    E = I * cos(theta) / (d^2 + r^2).  Soft falloff off: a sphere, E = I * cos(theta) / d^2.
    """
    x, y = pixel_centres()
    d2 = x * x + y * y + h * h
    cos_r = h / np.sqrt(d2)
    denom = d2 + (radius * radius if soft_falloff else 0.0)
    e = cos_r / denom
    if mask is not None:
        e = e * mask(x, y)
    return np.asarray(I) * e.mean()


def spot_mask(cos_angle, spot_size, spot_blend):
    """Cycles spot attenuation: smoothstep((cos a - cos(s/2)) / ((1 - cos(s/2)) * blend))."""
    c = math.cos(0.5 * spot_size)
    if spot_blend <= 0.0:
        return np.where(cos_angle > c, 1.0, 0.0)
    t = np.clip((cos_angle - c) / ((1.0 - c) * spot_blend), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def rect_irradiance(L, h, sx, sy, ellipse=False, spread=math.pi, n=1500):
    """Irradiance at the origin (normal +Z) from a Lambertian rectangle/ellipse of radiance L
    centred at height h facing down; optional Cycles spread attenuation (midpoint rule)."""
    u = ((np.arange(n) + 0.5) / n - 0.5) * sx
    v = ((np.arange(n) + 0.5) / n - 0.5) * sy
    X, Y = np.meshgrid(u, v)
    r2 = X * X + Y * Y
    f = h * h / (r2 + h * h) ** 2  # cos_receiver * cos_light / d^2
    if ellipse:
        f = f * (((X / (0.5 * sx)) ** 2 + (Y / (0.5 * sy)) ** 2) <= 1.0)
    if spread < math.pi:
        a = 0.5 * spread
        f = f * np.maximum(math.tan(a) - np.sqrt(r2) / h, 0.0) / (math.tan(a) - a)
    return L * f.sum() * (sx / n) * (sy / n)


# --------------------------------------------------------------------------- cases

ROWS = []


def record(name, predicted, image):
    meas = image.reshape(-1, 3).mean(axis=0)
    pred = np.broadcast_to(np.asarray(predicted, np.float64), (3,))
    ROWS.append((name, pred, meas))
    print(fmt_row(name, pred, meas), flush=True)


def fmt_val(v):
    if np.allclose(v, v[0], rtol=1e-4, atol=1e-9):
        return f"{v[0]:.5g}"
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


def fmt_ratio(pred, meas):
    if np.all(pred == 0.0):
        return "n/a (expect 0)" if np.all(np.abs(meas) < 1e-6) else "NONZERO"
    r = meas / pred
    if r.max() - r.min() < 5e-4:
        return f"{r.mean():.4f}"
    return f"{r.mean():.4f} [{r.min():.4f}..{r.max():.4f}]"


def fmt_row(name, pred, meas):
    return f"| {name} | {fmt_val(pred)} | {fmt_val(meas)} | {fmt_ratio(pred, meas)} |"


def lam(E):
    """Pixel of the diffuse receiver under irradiance E."""
    return ALBEDO / math.pi * np.asarray(E)


def case_point():
    P, h = 100.0, 2.0
    col = (1.0, 0.5, 0.25)
    for radius, soft, extra in [(0.0, True, {}), (0.1, True, {}), (1.0, True, {}), (1.0, False, {}),
                                (0.0, True, {"exposure": 1.0})]:
        sc = new_scene()
        receiver(sc)
        add_light(sc, "POINT", (0, 0, h), energy=P, color=col, shadow_soft_size=radius,
                  use_soft_falloff=soft, **extra)
        I = point_intensity(P, col, extra.get("exposure", 0.0))  # noqa: E741
        tag = "soft falloff" if soft else "sphere (soft falloff off)"
        ex = ", exposure=1" if extra else ""
        record(f"point P=100 r={radius} h=2 {tag}{ex}: pixel", lam(point_irradiance(I, h, radius, soft)),
               render(sc))
    # normalize=False: eval factor 1/pi instead of 1/(pi * area), area of a zero-radius light = 4
    sc = new_scene()
    receiver(sc)
    add_light(sc, "POINT", (0, 0, h), energy=P, shadow_soft_size=0.0, normalize=False)
    record("point r=0 normalize=False (I = P/pi): pixel",
           lam(point_irradiance(4.0 * point_intensity(P), h)), render(sc))
    # film exposure multiplies the whole image
    sc = new_scene()
    receiver(sc)
    sc.cycles.film_exposure = 2.0
    add_light(sc, "POINT", (0, 0, h), energy=P, shadow_soft_size=0.0)
    record("point r=0, film_exposure=2: pixel", 2.0 * lam(point_irradiance(point_intensity(P), h)), render(sc))
    # radiance of the light seen by a camera ray (object visible_camera)
    r = 0.5
    for soft, vis in [(True, True), (False, True), (True, None)]:
        sc = new_scene()
        add_camera(sc, 0.0, look_up=True, scale=0.2)
        add_light(sc, "POINT", (0, 0, 3.0), energy=P, color=col, shadow_soft_size=r,
                  use_soft_falloff=soft, visible_camera=vis)
        L = np.asarray(col) * P / (4.0 * math.pi ** 2 * r * r)
        if vis is None:
            record("point r=0.5 seen by camera, default visible_camera (False)", 0.0, render(sc))
        else:
            tag = "soft falloff" if soft else "sphere"
            record(f"point r=0.5 seen by camera ({tag}), visible_camera=True: L", L, render(sc))


def case_spot():
    P, h = 100.0, 2.0
    size, blend = math.radians(60.0), 0.5
    for tilt_deg in [0.0, 15.0, 22.0, 25.0, 28.0, 35.0]:
        sc = new_scene()
        receiver(sc)
        tilt = math.radians(tilt_deg)
        add_light(sc, "SPOT", (0, 0, h), rotation=(tilt, 0.0, 0.0), energy=P,
                  shadow_soft_size=0.0, spot_size=size, spot_blend=blend)
        axis = np.array([0.0, math.sin(tilt), -math.cos(tilt)])  # light -Z after rotation about X

        def mask(x, y, axis=axis):
            d = np.stack([x, y, -h * np.ones_like(x)], -1)
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
            return spot_mask(d @ axis, size, blend)

        pred = lam(point_irradiance(point_intensity(P), h, mask=mask))
        m0 = float(spot_mask(math.cos(tilt), size, blend))
        record(f"spot size=60 blend=0.5, {tilt_deg:g} deg off axis (mask {m0:.3f}): pixel", pred, render(sc))
    sc = new_scene()
    receiver(sc)
    add_light(sc, "SPOT", (0, 0, h), energy=P, shadow_soft_size=0.5, spot_size=size, spot_blend=blend)
    record("spot r=0.5 on axis, soft falloff (E = I/(d^2+r^2)): pixel",
           lam(point_irradiance(point_intensity(P), h, 0.5, True)), render(sc))
    sc = new_scene()
    receiver(sc)
    add_light(sc, "SPOT", (0, 0, h), rotation=(math.radians(25.0), 0, 0), energy=P,
              shadow_soft_size=0.0, spot_size=size, spot_blend=0.0)
    record("spot size=60 blend=0, 25 deg off axis (hard edge, mask 1): pixel",
           lam(point_irradiance(point_intensity(P), h)), render(sc))


def case_sun():
    S = 3.0
    for angle_deg, tilt_deg in [(0.526, 0.0), (0.526, 60.0), (10.0, 0.0), (10.0, 60.0)]:
        sc = new_scene()
        receiver(sc)
        add_light(sc, "SUN", (0, 0, 5), rotation=(math.radians(tilt_deg), 0, 0), energy=S,
                  angle=math.radians(angle_deg))
        record(f"sun S=3 angle={angle_deg:g} deg, incidence {tilt_deg:g} deg: pixel",
               lam(S * math.cos(math.radians(tilt_deg))), render(sc))
    sc = new_scene()
    receiver(sc)
    ang = math.radians(10.0)
    add_light(sc, "SUN", (0, 0, 5), energy=S, angle=ang, normalize=False)
    record("sun S=3 angle=10 deg normalize=False (L = S): pixel",
           lam(S * math.pi * math.sin(0.5 * ang) ** 2), render(sc))
    sc = new_scene()
    add_camera(sc, 0.0, look_up=True)
    add_light(sc, "SUN", (0, 0, 5), energy=S, angle=ang, visible_camera=True)
    record("sun S=3 angle=10 deg seen by camera, visible_camera=True: L",
           S / (math.pi * math.sin(0.5 * ang) ** 2), render(sc))


def case_area():
    P, h = 100.0, 1.5
    shapes = [
        ("SQUARE", dict(size=1.0), 1.0, 1.0, False, (1, 1, 1)),
        ("RECTANGLE", dict(size=2.0, size_y=0.5), 2.0, 0.5, False, (1, 1, 1)),
        ("DISK", dict(size=1.0), 1.0, 1.0, True, (1, 1, 1)),
        ("ELLIPSE", dict(size=2.0, size_y=0.5), 2.0, 0.5, True, (1, 1, 1)),
        ("SQUARE", dict(size=0.5), 1.0, 1.0, False, (2, 2, 1)),
    ]
    for shape, props, sx, sy, ell, scale in shapes:
        sc = new_scene()
        receiver(sc)
        add_light(sc, "AREA", (0, 0, h), scale=scale, energy=P, shape=shape, **props)
        A = sx * sy * (math.pi / 4.0 if ell else 1.0)
        L = P / (math.pi * A)
        dims = " x ".join(f"{v:g}" for v in (props["size"], props.get("size_y", props["size"])))
        sc_txt = "" if scale == (1, 1, 1) else f" object scale {scale[0]}x{scale[1]}"
        record(f"area {shape} {dims}{sc_txt} P=100 h=1.5: pixel", lam(rect_irradiance(L, h, sx, sy, ell)),
               render(sc))
    # spread
    sc = new_scene()
    receiver(sc)
    sp = math.radians(60.0)
    add_light(sc, "AREA", (0, 0, h), energy=P, shape="SQUARE", size=1.0, spread=sp)
    record("area SQUARE 1 x 1 spread=60 deg: pixel", lam(rect_irradiance(P / math.pi, h, 1, 1, spread=sp)),
           render(sc))
    # normalize off: radiance P / pi independent of area
    sc = new_scene()
    receiver(sc)
    add_light(sc, "AREA", (0, 0, h), energy=P, shape="RECTANGLE", size=2.0, size_y=1.0, normalize=False)
    record("area RECTANGLE 2 x 1 normalize=False (L = P/pi): pixel",
           lam(rect_irradiance(P / math.pi, h, 2.0, 1.0)), render(sc))
    # seen directly
    L = P / (math.pi * 2.0 * 0.5)
    for look_up, vis, label, pred in [
        (True, True, "area 2 x 0.5 seen from below (front), visible_camera=True: L", L),
        (True, None, "area seen from below, default visible_camera (False)", 0.0),
        (False, True, "area seen from above (back side), visible_camera=True", 0.0),
    ]:
        sc = new_scene()
        add_camera(sc, 0.0 if look_up else 3.0, look_up=look_up)
        add_light(sc, "AREA", (0, 0, h), energy=P, shape="RECTANGLE", size=2.0, size_y=0.5,
                  visible_camera=vis)
        record(label, pred, render(sc))
    # seen in a perfect mirror (visible_glossy default True)
    sc = new_scene(max_bounces=1)
    add_quad(sc, "Mirror", 20.0, 20.0, 0.0, material("mirror", (1.0, 1.0, 1.0), roughness=0.0))
    add_camera(sc, 0.5)
    add_light(sc, "AREA", (0, 0, h), energy=P, shape="RECTANGLE", size=2.0, size_y=0.5)
    record("area 2 x 0.5 in a mirror (Glossy r=0), default visibility: L", L, render(sc))


def case_mesh_emission():
    col, S = (1.0, 0.5, 0.25), 3.0
    for kind, normal_up, label in [
        ("emission", False, "Emission C*S, front face seen by camera: L"),
        ("emission", True, "Emission C*S, back face seen by camera: L"),
        ("principled_emission", False, "Principled Emission Color*Strength (base black): L"),
    ]:
        sc = new_scene()
        add_quad(sc, "Emitter", 1.0, 1.0, 1.0, material(kind, col, S), normal_up=normal_up)
        add_camera(sc, 0.0, look_up=True)
        record(label, np.asarray(col) * S, render(sc))
    # as a light source: 1 x 1 emissive quad facing down at h = 1.5
    h = 1.5
    sc = new_scene()
    receiver(sc)
    add_quad(sc, "Emitter", 1.0, 1.0, h, material("emission", col, S), normal_up=False)
    record("Emission quad 1 x 1 C*S at h=1.5 lighting diffuse: pixel",
           lam(rect_irradiance(np.asarray(col) * S, h, 1.0, 1.0)), render(sc))
    sc = new_scene()
    receiver(sc)
    add_quad(sc, "Emitter", 1.0, 1.0, h, material("emission", col, S), normal_up=True)
    record("same quad with its back face towards the receiver: pixel",
           lam(rect_irradiance(np.asarray(col) * S, h, 1.0, 1.0)), render(sc))


def case_world():
    col, S = (0.2, 0.4, 0.6), 2.0
    sc = new_scene()
    sc.world = make_world(col, S)
    add_camera(sc, 0.0, look_up=True)
    record("world Background C*S seen by camera: L", np.asarray(col) * S, render(sc))
    sc = new_scene()
    sc.world = make_world(col, S)
    receiver(sc)
    record("world C*S on diffuse plane (E = pi C S): pixel", ALBEDO * np.asarray(col) * S, render(sc))


def main():
    t0 = time.time()
    print(f"Blender {bpy.app.version_string}, Cycles CPU 2 threads, {RES}x{RES} px, {SPP} spp, "
          f"receiver albedo {ALBEDO}")
    print("| case | predicted | measured | measured/predicted |")
    print("|---|---|---|---|")
    for case in (case_point, case_spot, case_sun, case_area, case_mesh_emission, case_world):
        case()
    bad = [r for r in ROWS if np.any(r[1] != 0) and np.max(np.abs(r[2] / np.where(r[1] == 0, 1, r[1]) - 1)) > 0.01]
    bad += [r for r in ROWS if np.all(r[1] == 0) and np.any(np.abs(r[2]) > 1e-6)]
    print(f"{len(ROWS)} cases, {len(bad)} off by more than 1%, {time.time() - t0:.0f} s")
    shutil.rmtree(TMP, ignore_errors=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
