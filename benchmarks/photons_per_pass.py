"""Photons per pass at high resolution: error at equal time for several photon counts.

A pass is an eye pass (one measurement point per pixel, the hash grid over them) and a
photon pass.  The main process prepares the next eye pass while the workers trace the
photons of this one, so when the photon pass is shorter than that preparation the workers
wait.  At 1920x1080 the preparation takes seconds; this measures what a photon count per
worker costs and gives in error at equal render time, with the product's default worker
count (one per core), one run at a time.

Errors are relMSE corrected for the reference's noise, as in ``error_vs_time.py``: the
reference is the mean of two independent long runs A and B (seeds 1001/1002, radii r0 and
r0/2), written to ``benchmarks/results/photons_per_pass/`` (a 1080p reference is too big
for git) and reused unless ``--make-reference`` is given.

    python benchmarks/photons_per_pass.py --scene cornell_box --method ppm \\
        --resolution 1920 1080 --photons 100000 250000 500000 --time 90 --seeds 2
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from error_vs_time import METHODS, errors, git_commit  # noqa: E402

OUT = os.path.join(ROOT, "benchmarks", "results", "photons_per_pass")


def run_one(scene_name, resolution, method, seed, time_limit, photons, out_path, radius_scale=1.0,
            reference=None):
    """One render in this process; keeps the last image (reference halves) or the error per pass."""
    from core import RenderSettings, render
    from core.testing.scenes import BUILTIN

    scene = BUILTIN[scene_name](resolution=tuple(resolution))
    r0 = RenderSettings().initial_radius_px
    settings = RenderSettings(**METHODS[method], seed=seed, passes=0, time_limit=time_limit,
                              photons_per_pass=photons, initial_radius_px=r0 * radius_scale)
    rows = []
    if reference is not None:
        z = np.load(reference)
        ref = z["image"]
        ref_var = (z["half_a"] - z["half_b"]) ** 2 / 4.0

    def keep(result):
        s = result.stats[-1]
        row = dict(elapsed=s["elapsed_s"], paths=s["paths_traced"], photon_s=s["photon_s"],
                   prepare_s=s["prepare_next_s"], photons=s["photons_per_pass"])
        if reference is not None:
            row["relmse_c"] = float(errors(result.image[None], ref, ref_var)[3][0])
        rows.append(row)

    result = render(scene, settings, on_iteration=keep)
    image = result.image[..., :3].astype(np.float32) if reference is None else np.zeros(0)
    np.savez_compressed(out_path, image=image, rows=json.dumps(rows))


def error_at(rows, t):
    """relMSE of the last image finished by time t."""
    done = [x["relmse_c"] for x in rows if x["elapsed"] <= t]
    return done[-1] if done else float("nan")


def launch(*args):
    subprocess.run([sys.executable, os.path.abspath(__file__), "--run-one", json.dumps(args)], check=True)


def reference_path(scene, method, resolution):
    return os.path.join(OUT, f"reference_{scene}_{method}_{resolution[0]}x{resolution[1]}.npz")


def make_reference(a, photons):
    halves = []
    for seed, scale in ((1001, 1.0), (1002, 0.5)):
        path = os.path.join(OUT, f"ref_{a.scene}_{seed}.npz")
        launch(a.scene, a.resolution, a.method, seed, a.reference_time, photons, path, scale)
        halves.append(np.load(path)["image"])
    np.savez_compressed(reference_path(a.scene, a.method, a.resolution), image=0.5 * (halves[0] + halves[1]),
                        half_a=halves[0], half_b=halves[1],
                        meta=json.dumps(dict(seconds_per_half=a.reference_time, photons=photons,
                                             commit=git_commit())))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run-one", help=argparse.SUPPRESS)
    ap.add_argument("--scene", default="cornell_box")
    ap.add_argument("--method", default="ppm", choices=list(METHODS))
    ap.add_argument("--resolution", type=int, nargs=2, default=(1920, 1080))
    ap.add_argument("--photons", type=int, nargs="+", default=[100_000, 250_000, 500_000],
                    help="photon paths per pass and worker to compare (0 = automatic)")
    ap.add_argument("--time", type=float, default=90.0, help="seconds per run")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--reference-time", type=float, default=300.0, help="seconds per reference half")
    ap.add_argument("--make-reference", action="store_true")
    a = ap.parse_args()
    if a.run_one:
        run_one(*json.loads(a.run_one))
        return
    os.makedirs(OUT, exist_ok=True)
    ref = reference_path(a.scene, a.method, a.resolution)
    if a.make_reference or not os.path.exists(ref):
        make_reference(a, max(a.photons))
    results = {}
    for seed in range(a.seeds):                 # interleaved: every count sees the same machine load
        for n in a.photons:
            path = os.path.join(OUT, f"run_{a.scene}_{a.method}_{n}_{seed}.npz")
            launch(a.scene, a.resolution, a.method, seed, a.time, n, path, 1.0, ref)
            results.setdefault(n, []).append(json.loads(str(np.load(path)["rows"])))
    w, h = a.resolution
    lines = [f"# Photons per pass: {a.scene}, {a.method}, {w}x{h}, {a.time:g} s per run, {a.seeds} seeds, "
             f"{os.cpu_count()} workers", "",
             f"Commit {git_commit()[:10]}, {platform.node()}, {time.strftime('%Y-%m-%d %H:%M')}; reference "
             f"2 x {a.reference_time:g} s.", "",
             "The error at T is that of the image the render returns (a pass still running at the time "
             "limit is cut there), returned at the time given; at T/2, of the last image shown by then.", "",
             "| photons per pass and worker | per pixel (all workers) | passes | paths traced "
             "| photon s / pass | prepare s / pass | corrected relMSE at T/2 | at T (per seed) "
             "| at T, relative to the first row | returned at (s) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    base = None
    for n in a.photons:
        runs = results[n]
        finals = [r[-1]["relmse_c"] for r in runs]
        err = float(np.median(finals))
        half = float(np.median([error_at(r, a.time / 2) for r in runs]))
        base = base or err
        passes = np.median([len(r) for r in runs])
        paths = np.median([sum(x["paths"] for x in r) for r in runs])
        ph = np.median([np.median([x["photon_s"] for x in r]) for r in runs])
        prep = np.median([np.median([x["prepare_s"] for x in r[:-1]] or [0]) for r in runs])
        full = runs[0][-1]["photons"] if n == 0 else n
        per_px = full * (os.cpu_count() or 1) / (w * h)
        per_seed = ", ".join(f"{e:.3g}" for e in finals)
        label = f"automatic ({', '.join(f'{x:,}' for x in dict.fromkeys(r['photons'] for r in runs[0]))})" \
            if n == 0 else f"{n:,}"
        returned = np.median([r[-1]["elapsed"] for r in runs])
        lines.append(f"| {label} | {per_px:.2f} | {passes:.0f} | {paths:,.0f} | {ph:.2f} | {prep:.2f} | "
                     f"{half:.4g} | {err:.4g} ({per_seed}) | {err / base:.2f} | {returned:.1f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    with open(os.path.join(OUT, f"report_{a.scene}_{a.method}_{w}x{h}.md"), "w") as f:
        f.write(text)


if __name__ == "__main__":
    main()
