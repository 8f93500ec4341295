"""The report of bench/sweep.py: OUTPUT.md, counts per mode, the problems
and a table with one row per file (no bpy here)."""

from __future__ import annotations

import argparse
import os
import re

MODE_TITLES = {"PATH": "Path Tracing", "RESTIR_BIASED": "ReSTIR Biased",
               "RESTIR_UNBIASED": "ReSTIR Unbiased"}
STATUSES = ("rendered", "failed", "crashed", "timeout", "nan")


def cell(entry: dict | None) -> str:
    if entry is None:
        return "-"
    status = entry["status"]
    if status == "rendered":
        return "{:.1f} s".format(entry["seconds"])
    if status == "nan":
        return "**NaN** {} px, {:.1f} s".format(entry["bad_pixels"], entry["seconds"])
    return "**{}**".format(status)


def write_report(path: str, args: argparse.Namespace, files: list[str], skipped: list[str],
                 results: dict, command: str) -> None:
    modes = args.modes
    lines = ["# Sweep: {} files, {}".format(len(files), ", ".join(MODE_TITLES[m] for m in modes)), ""]
    lines += ["```sh", command, "```", ""]
    lines += ["{}, {} warm-up frames (ReSTIR), {} samples (Path Tracing), {} s limit per "
              "render{}.".format("{}x{}".format(*args.size), args.warmup,
                                 args.samples if args.samples else "the file's",
                                 "{:g}".format(args.timeout),
                                 ", camera framing all visible objects" if args.camera else ""), ""]
    lines += ["| mode | files | " + " | ".join(STATUSES) + " | median time |",
              "|---|---:|" + "---:|" * len(STATUSES) + "---:|"]
    for mode in modes:
        done = [results[(f, mode)] for f in files if (f, mode) in results]
        counts = [sum(e["status"] == s for e in done) for s in STATUSES]
        times = sorted(e["seconds"] for e in done if e.get("seconds") is not None)
        median = "{:.1f} s".format(times[len(times) // 2]) if times else "-"
        lines.append("| {} | {} | {} | {} |".format(MODE_TITLES[mode], len(done),
                                                    " | ".join(map(str, counts)), median))
    lines += ["", "Times are the render alone (Blender's start-up and the file's loading "
                  "not counted).", ""]
    problems = [results[(f, m)] for f in files for m in modes
                if (f, m) in results and results[(f, m)]["status"] != "rendered"]
    if problems:
        lines += ["## Problems", "", "| file | mode | result | error |", "|---|---|---|---|"]
        for e in problems:
            error = e.get("error", "")
            if e.get("where"):
                error += " (at {})".format(e["where"])
            if e["status"] == "nan":
                error = "{} NaN, {} Inf pixels (passes: {})".format(
                    e.get("nan_pixels", 0), e.get("inf_pixels", 0),
                    ", ".join(sorted(e.get("bad_passes", {}))))
            lines.append("| {} | {} | {} | {} |".format(
                e["file"], MODE_TITLES[e["mode"]], e["status"], error.replace("|", "\\|")))
        lines.append("")
    lines += ["## Files", "", "| file | " + " | ".join(MODE_TITLES[m] for m in modes) + " |",
              "|---|" + "---:|" * len(modes)]
    for f in files:
        lines.append("| {} | {} |".format(f.replace(os.sep, "/"),
                                          " | ".join(cell(results.get((f, m))) for m in modes)))
    if skipped:
        lines += ["", "Skipped (not .blend files, e.g. Git LFS pointers): "
                  + ", ".join(s.replace(os.sep, "/") for s in skipped) + "."]
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def display_command(argv: list[str], args: argparse.Namespace) -> str:
    """The command line as given, with the folder written DIR and other
    absolute paths by their role, so the report names no path of this machine."""
    placeholders = {"--logs": "LOGDIR", "--images": "IMGDIR", "--package": "ZIP", "--user-resources": "USERDIR",
                    "--output": "OUTPUT"}
    words, previous = ["python bench/sweep.py"], None
    for arg in argv:
        if arg == args.folder:
            arg = "DIR"
        elif previous in placeholders and os.path.isabs(arg):
            arg = placeholders[previous]
        elif "=" in arg and arg.split("=", 1)[0] in placeholders and os.path.isabs(arg.split("=", 1)[1]):
            arg = "{}={}".format(arg.split("=", 1)[0], placeholders[arg.split("=", 1)[0]])
        words.append(arg if re.fullmatch(r"[\w.,:=/+-]+", arg) else repr(arg))
        previous = arg
    return " ".join(words)
