"""Cycles references of bench/equal_time.py, cached in bench/out/refs/, and
what renders them."""

import hashlib
import json

from bench_common import OUT, ROOT, render_frames

REF_SEED = 1234
REF_SECONDS = []            # render times of the references rendered in this run


def cycles(spp, seed, animated):
    def setup(scene):
        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.device = "CPU"
        c.samples = spp
        c.seed = seed
        c.use_animated_seed = animated
        c.use_denoising = False
        c.use_adaptive_sampling = False
    return setup


def cycles_denoised(spp, seed, animated):
    """bench setup: Cycles at ``spp`` with its own Denoise (OIDN, albedo and
    normal, accurate prefilter, high quality, CPU)."""
    plain = cycles(spp, seed, animated)

    def setup(scene):
        plain(scene)
        c = scene.cycles
        c.use_denoising = True
        c.denoiser = "OPENIMAGEDENOISE"
        c.denoising_input_passes = "RGB_ALBEDO_NORMAL"
        c.denoising_prefilter = "ACCURATE"
        c.denoising_quality = "HIGH"
        c.denoising_use_gpu = False
    return setup


def mse(img, ref):
    return float(((img - ref) ** 2).mean())


def report(label, reports):
    for line in reports:
        print(f"    [{label}] {line}", flush=True)


def reference(blend, name, camera, frame, spp, size, halves=False):
    """Cached Cycles reference of ``frame`` at ``spp``; (image, seconds to
    render it, whether it was cached, its noise). With ``halves`` it is the
    mean of two renders of spp / 2 with different seeds, and its noise (the
    expected MSE it adds) is estimated from their difference: MSE(a, b) / 4;
    otherwise the noise is None."""
    from restir_gi.core.camera.film import read_exr, write_exr
    sha = hashlib.sha1(blend.read_bytes()).hexdigest()[:12]
    w, h = size
    refs = OUT / "refs"
    stem = f"{name}_{camera}_f{frame}_{w}x{h}_{spp}spp{'_halves' if halves else ''}_{sha}"
    path, meta = refs / f"{stem}.exr", refs / f"{stem}.json"
    if path.exists() and meta.exists():
        info = json.loads(meta.read_text())
        return read_exr(path), info["seconds"], True, info.get("noise")
    print(f"  reference: Cycles {spp} spp of frame {frame} ({camera}) ...", flush=True)
    pin = 1 if camera == "still" else None
    seeds = (REF_SEED, REF_SEED + 1) if halves else (REF_SEED,)
    imgs, t, noise = [], 0.0, None
    for seed in seeds:
        images, seconds, reps = render_frames(blend, [frame], cycles(spp // len(seeds), seed, False), pin=pin)
        report("reference", reps)
        imgs.append(images[frame])
        t += seconds[frame]
    img = sum(imgs) / len(imgs)
    if halves:
        noise = mse(imgs[0], imgs[1]) / 4
    refs.mkdir(parents=True, exist_ok=True)
    write_exr(path, img)
    meta.write_text(json.dumps({"seconds": t, "blend": blend.name, "camera": camera, "frame": frame,
                                "spp": spp, "seed": REF_SEED, "halves": halves, "noise": noise}))
    print(f"  reference took {t:.0f} s, cached as {path.relative_to(ROOT)}", flush=True)
    REF_SECONDS.append(t)
    return img, t, False, noise
