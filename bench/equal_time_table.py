"""The markdown tables of bench/equal_time.py (rows: dicts of run_case and
lag_rows; a missing value prints as '-')."""

import math
import statistics


def fmt(v, spec, suffix=""):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec) + suffix


def table(results, args, pt_frames, cycles_frames):
    w, h = round(320 * getattr(args, "scale", 1.0)), round(180 * getattr(args, "scale", 1.0))
    lines = [f"Corpus at {w}x{h} (files' settings: 12/4/4/12 bounces in both engines, no clamping "
             f"in Cycles), frame N = {args.frames}, reference Cycles {args.ref_spp} spp. "
             f"ms per frame: median of frames 2..N (PT: {pt_frames} frames, Cycles: "
             f"{cycles_frames} frames, camera held at frame N; reference: its single frame). "
             f"Reference row's MSE: its own estimated noise. 'vs C+OIDN': Cycles + OIDN at the "
             f"row's time per frame, its MSE / ours, its FLIP / ours, our flicker / its.", "",
             "| scene | camera | method | ms / frame | MSE | FLIP | flicker | gain vs PT | "
             "gain vs Cycles | MSE vs C+OIDN | FLIP vs C+OIDN | flicker vs C+OIDN | mean ratio | black % |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for (name, camera), rows in results.items():
        for r in rows:
            lines.append(
                f"| {name} | {camera} | {r['method']} | {r['t'] * 1000:.0f} | {fmt(r['mse'], '.4g')} | "
                f"{fmt(r.get('flip'), '.4f')} | {fmt(r.get('flicker'), '.2e')} | "
                f"{fmt(r.get('g_pt'), '.1f', 'x')} | {fmt(r.get('g_c'), '.1f', 'x')} | "
                f"{fmt(r.get('g_co'), '.2f', 'x')} | {fmt(r.get('f_co'), '.2f', 'x')} | "
                f"{fmt(r.get('k_co'), '.3f')} | {fmt(r.get('ratio'), '.3f')} | {fmt(r.get('black'), '.2f')} |")
    # Geometric means of the gains over the scenes, per method and camera.
    summary = {}
    for (_name, camera), rows in results.items():
        for r in rows:
            if r["method"].startswith("ReSTIR") and r.get("g_pt") is not None:
                summary.setdefault((r["method"], camera), []).append(r)
    keys = ("g_pt", "g_c", "g_co", "f_co", "k_co")
    if summary:
        lines += ["", "| method | camera | scenes | geo. mean gain vs PT | vs Cycles | MSE vs C+OIDN | "
                  "FLIP vs C+OIDN | flicker vs C+OIDN | worst MSE vs C+OIDN |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for (method, camera), rs in summary.items():
            gm = []
            for k in keys:
                vals = [r[k] for r in rs if r.get(k)]
                gm.append(math.exp(statistics.mean(math.log(v) for v in vals)) if vals else None)
            worst = min((r["g_co"] for r in rs if r.get("g_co")), default=None)
            lines.append(f"| {method} | {camera} | {len(rs)} | {fmt(gm[0], '.1f', 'x')} | "
                         f"{fmt(gm[1], '.1f', 'x')} | {fmt(gm[2], '.2f', 'x')} | {fmt(gm[3], '.2f', 'x')} | "
                         f"{fmt(gm[4], '.3f')} | {fmt(worst, '.2f', 'x')} |")
    return "\n".join(lines)


def lag_table(lags, args, still):
    lines = [f"Lag (moving camera): {still} + 1 frames at the camera's first pose, its move (file "
             f"frames 2..{args.frames}), then held at its last pose. MSE (FLIP) of the last frame "
             f"before the move (against the still reference), of the first frame after the motion "
             f"starts (MSE only: against a Cycles reference at {args.ref_spp // 4} spp whose own "
             f"noise, estimated from two halves, is subtracted), of the last moving frame and of "
             f"the two frames right after it stops. C+OIDN: Cycles + OIDN's MSE (FLIP) at the "
             f"row's time per frame on the moving camera (it carries no history).", "",
             "| scene | method | ms / frame | before | start | moving | stop | C+OIDN |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]

    def cell(r, key):
        flip = r.get(key + "_flip")
        return fmt(r.get(key), ".4g") + ("" if flip is None else f" ({flip:.3f})")

    for r in lags:
        c = f"{fmt(r.get('c_mse'), '.4g')} ({fmt(r.get('c_flip'), '.3f')})"
        lines.append(f"| {r['scene']} | {r['method']} | {r['t'] * 1000:.0f} | {cell(r, 'before')} | "
                     f"{cell(r, 'start')} | {cell(r, 'moving')} | {cell(r, 'stop')} | {c} |")
    return "\n".join(lines)
