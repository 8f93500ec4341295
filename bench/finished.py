"""Finished frames for bench/equal_time.py: Intel Open Image Denoise (OIDN)
on both engines, HDR-FLIP, flicker, Cycles' curve with its own denoiser, and
the camera schedule of the lag runs.

* OIDN on ours: the ``pyoidn`` package (OIDN 2.5, as Blender 5.2 bundles)
  on the Combined pass with the Denoising Albedo and Denoising Normal passes,
  as Cycles' own Denoise runs it: RT filter, HDR, quality high, the
  auxiliary passes prefiltered by OIDN first (Cycles' "Accurate" prefilter).
* Cycles + OIDN: Cycles' own Denoise (Render Properties > Sampling >
  Denoise: OpenImageDenoise, Albedo and Normal, Accurate, High, CPU); its
  time is inside the frame's.
* HDR-FLIP: NVIDIA's perceptual error (the ``flip-evaluator`` package),
  mean over the image, on the linear images against the reference, its
  exposures chosen by FLIP from the reference.
* Flicker: mean squared difference between consecutive frames, over all RGB
  values, divided by the reference's mean square (still camera: the view
  does not change, so any difference is noise that moves).

Both packages are bench-only (requirements-bench.txt); the engine and the
tests do not need them.
"""

import math
import time

import numpy as np

CYCLES_OIDN_SPP = (1, 2, 4, 8, 16, 32)
AUX = ("Denoising Albedo", "Denoising Normal")


class _OIDN:
    """An OIDN CPU device with three RT filters, made once: the albedo's and
    the normal's prefilters and the colour's (cleanAux, HDR, quality high),
    as Cycles' Denoise with the "Accurate" prefilter runs them."""

    def __init__(self):
        import pyoidn
        self.p = pyoidn
        self.device = pyoidn.Device()
        self.device.commit()
        self.filters = {}

    def run(self, kind, inputs, out):
        p = self.p
        flt = self.filters.get(kind)
        if flt is None:
            flt = self.filters[kind] = p.Filter(self.device, p.OIDN_FILTER_TYPE_RT)
        for name, img in inputs.items():
            flt.set_image(name, img, p.OIDN_FORMAT_FLOAT3)
        flt.set_image(p.OIDN_IMAGE_OUTPUT, out, p.OIDN_FORMAT_FLOAT3)
        if kind == "color":
            flt.set_bool("hdr", True)
            flt.set_bool("cleanAux", True)
        flt.set_quality(p.OIDN_QUALITY_HIGH)
        flt.commit()
        flt.execute()

    def __call__(self, color, albedo, normal):
        p = self.p
        albedo_f, normal_f, out = np.empty_like(albedo), np.empty_like(normal), np.empty_like(color)
        self.run("albedo", {p.OIDN_IMAGE_ALBEDO: albedo}, albedo_f)
        self.run("normal", {p.OIDN_IMAGE_NORMAL: normal}, normal_f)
        self.run("color", {p.OIDN_IMAGE_COLOR: color, p.OIDN_IMAGE_ALBEDO: albedo_f,
                           p.OIDN_IMAGE_NORMAL: normal_f}, out)
        return out


_DENOISER = []


def oidn(passes):
    """(image, seconds): OIDN on a frame's {"Combined", "Denoising Albedo",
    "Denoising Normal"} (H, W, 3) arrays, as Cycles' Denoise runs it
    (albedo and normal prefiltered, then the colour with them as clean
    auxiliary images)."""
    if not _DENOISER:
        _DENOISER.append(_OIDN())
    color = np.ascontiguousarray(np.clip(passes["Combined"], 0.0, None), np.float32)
    albedo = np.ascontiguousarray(np.clip(passes["Denoising Albedo"], 0.0, 1.0), np.float32)
    normal = np.ascontiguousarray(np.clip(passes["Denoising Normal"], -1.0, 1.0), np.float32)
    t0 = time.perf_counter()
    out = _DENOISER[0](color, albedo, normal)
    return out, time.perf_counter() - t0


def warm_oidn(shape):
    """Run OIDN once (device and filters set up, weights loaded) so that the
    timed calls measure a frame's denoising only, as in a running Cycles."""
    z = np.full(shape, 0.5, np.float32)
    oidn({"Combined": z, "Denoising Albedo": z, "Denoising Normal": z})


def flip(img, ref):
    """Mean HDR-FLIP of img against ref (both (H, W, 3) linear)."""
    import flip_evaluator
    _, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(np.clip(ref, 0, None), np.float32),
                                         np.ascontiguousarray(np.clip(img, 0, None), np.float32),
                                         "HDR", applyMagma=False)
    return float(mean)


def flicker(frames, ref):
    """Mean over consecutive pairs of frames of their mean squared
    difference, relative to the reference's mean square; None for fewer than
    two frames."""
    if len(frames) < 2:
        return None
    scale = float((ref.astype(np.float64) ** 2).mean())
    diffs = [float(((a - b) ** 2).mean()) for a, b in zip(frames, frames[1:])]
    return sum(diffs) / len(diffs) / scale


class Curve:
    """A Cycles curve over samples per pixel: points {spp: {"t": seconds per
    frame, metric: value}}. The time per frame is fitted as a + b spp (least
    squares: single frames' times are noisy on a shared machine); at a time t
    the curve's spp is (t - a) / b, at least its smallest spp (never faster
    than its 1-spp frame), and each metric is interpolated in log-log over
    spp between its neighbouring points, extrapolated beyond the last along
    the last segment."""

    def __init__(self, points):
        self.points = dict(sorted(points.items()))
        spp = np.array(list(self.points), np.float64)
        t = np.array([p["t"] for p in self.points.values()], np.float64)
        if len(spp) > 1:
            b, a = np.polyfit(spp, t, 1)
        else:
            a, b = 0.0, t[0] / spp[0]
        self.a, self.b = float(a), float(max(b, 1e-9))

    def spp_at(self, t):
        return max(min(self.points), (t - self.a) / self.b)

    def at(self, t, metric):
        s = self.spp_at(t)
        xs = [k for k, p in self.points.items() if p.get(metric) is not None and p[metric] > 0]
        if not xs:
            return None
        if len(xs) == 1 or s <= xs[0]:
            return self.points[xs[0]][metric]
        i = max(j for j in range(len(xs) - 1) if xs[j] <= s) if s < xs[-1] else len(xs) - 2
        x0, x1 = xs[i], xs[i + 1]
        y0, y1 = math.log(self.points[x0][metric]), math.log(self.points[x1][metric])
        f = (math.log(s) - math.log(x0)) / (math.log(x1) - math.log(x0))
        return math.exp(y0 + f * (y1 - y0))


# ---------------------------------------------------------------- lag runs

def lag_schedule(still, frames, hold):
    """Frame -> frame of the file's camera animation: ``still`` + 1 frames at
    its frame-1 pose, then its move (frames 2..``frames``), then ``hold``
    frames at its last pose. Returns (schedule {frame: file frame}, first
    moving frame, first frame after the move stopped)."""
    sched = {}
    total = still + frames + hold
    for f in range(1, total + 1):
        sched[f] = min(max(f - still, 1), frames)
    start = still + 2
    stop = still + frames + 1
    return sched, start, stop


def retime_camera(scene, schedule):
    """Key the scene camera at every frame of ``schedule`` with its pose at
    the file's frame schedule[frame] (constant between keys)."""
    cam = scene.camera
    poses = {}
    for g in sorted(set(schedule.values())):
        scene.frame_set(g)
        poses[g] = cam.matrix_world.copy()
    cam.animation_data_clear()
    cam.rotation_mode = "QUATERNION"
    for f, g in schedule.items():
        cam.matrix_world = poses[g]
        cam.keyframe_insert("location", frame=f)
        cam.keyframe_insert("rotation_quaternion", frame=f)
        cam.keyframe_insert("scale", frame=f)
    for fc in _fcurves(cam.animation_data.action):
        for k in fc.keyframe_points:
            k.interpolation = "CONSTANT"
    scene.frame_set(1)


def _fcurves(action):
    """An action's F-curves: Blender 4.4+ keeps them in layered channelbags."""
    curves = getattr(action, "fcurves", None)
    if curves is not None and len(curves):
        return list(curves)
    out = []
    for layer in getattr(action, "layers", ()):
        for strip in layer.strips:
            for bag in strip.channelbags:
                out += list(bag.fcurves)
    return out
