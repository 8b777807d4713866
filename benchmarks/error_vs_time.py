"""What accuracy costs in time: error-versus-time curves and a time-to-error table (the paper's Table 1).

For each scene (the seed paper's three kinds: a room lit through a glass roof, a sun
through a hole onto a mirror and a glass object, a long lens on a small part of a big
scene) and each method:

    ppm            stochastic progressive photon mapping, uniform photons (the baseline)
    original       AMCMCPPM, target acceptance 23.4 %, full mutation (Hachisuka & Jensen 2011)
    a60            AMCMCPPM, target acceptance 60 %, full mutation
    a60-paper      ... plus the paper's low-dimension mutation (Watanabe et al.)
    a60-exact      ... plus the detailed-balance-preserving low-dimension mutation (our default)
    auto           a60-exact's first pass, then uniform photons if many uniform paths are visible
    ppm-uncorrected, a60-exact-uncorrected
                   ppm and a60-exact without the kernel-bias correction (RenderSettings.bias_correction)

every run is a separate process (``--jobs`` at a time, one worker each) that keeps the
image after every pass.  Errors are RMSE and relMSE = mean((I - R)^2 / (R^2 + 0.01)) on
linear RGB against a reference R: the mean of two long independent runs A and B started
with different seeds and the same initial radius, ``--reference-radius`` (1/4) of the
runs', stored in ``benchmarks/references`` with its metadata and split-half error, and never
overwritten unless ``--make-reference`` is given.  A reference this cheap is itself noisy,
so the errors are also reported *corrected* for its noise: E(I - R)^2 = E(I - T)^2 + Var R
per pixel, and (A - B)^2 / 4 estimates Var R without bias when A and B have the same
expectation, so mean((I - R)^2 - (A - B)^2 / 4) estimates the true mean squared error
(likewise for relMSE).  The halves share their radius for that reason: halves at r0 and r0/2
(references made before 2026-11-27, ``radius_scales`` in their metadata) differ by their
kernel bias as well, which the correction then takes for noise; on a bright caustic (the
sun through a hole, 64x48) that difference was larger than the errors measured.  The
smaller radius keeps the reference's own kernel bias below the runs'.  The references are
rendered without the kernel-bias correction (``REFERENCE_METHOD``, as all made before it), so
their own kernel bias, a sixteenth of the uncorrected runs', stays in them and bounds how low a
corrected run's error can be measured; they have the edge coverage
(``RenderSettings.edge_coverage``) since the references of 2026-11-27 16:00 (``edge_coverage`` in
their metadata), so surfaces' edges come out at their brightness instead of darkened by the part
of the kernel beyond them.  The time-to-error table uses the corrected relMSE, which bright
caustic pixels do not dominate.

    python benchmarks/error_vs_time.py --resolution 64 48 --time 60 --seeds 3 --jobs 2

writes ``benchmarks/results/error_vs_time/`` (per-run images, curves.png, report.md,
summary.json).  ``--quick`` is a two-minute smoke run at tiny sizes.  ``--make-reference SCENE
--analyse-only`` remakes a reference and measures the runs saved there against it again.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

METHODS = {
    "ppm": dict(method="ppm"),
    "original": dict(method="amcmcppm", target_acceptance=0.234, mutation="off"),
    "a60": dict(method="amcmcppm", target_acceptance=0.60, mutation="off"),
    "a60-paper": dict(method="amcmcppm", target_acceptance=0.60, mutation="paper"),
    "a60-exact": dict(method="amcmcppm", target_acceptance=0.60, mutation="exact"),
    "auto": dict(method="auto", target_acceptance=0.60, mutation="exact"),
    # The same without the kernel-bias correction (RenderSettings.bias_correction), as before it.
    "ppm-uncorrected": dict(method="ppm", bias_correction=False),
    "a60-exact-uncorrected": dict(method="amcmcppm", target_acceptance=0.60, mutation="exact",
                                  bias_correction=False),
    # The same without the edge coverage (RenderSettings.edge_coverage), as before it.
    "ppm-no-edges": dict(method="ppm", edge_coverage=False),
    "a60-exact-no-edges": dict(method="amcmcppm", target_acceptance=0.60, mutation="exact",
                               edge_coverage=False),
    # The same with each pass's pixel jitter drawn anew (RenderSettings.pixel_jitter), as before
    # the stratified jitter.
    "ppm-random-jitter": dict(method="ppm", pixel_jitter="random"),
    "a60-exact-random-jitter": dict(method="amcmcppm", target_acceptance=0.60, mutation="exact",
                                    pixel_jitter="random"),
    # The same with the photons from afar starting anywhere (RenderSettings.focus_photons), as
    # before the focus.
    "ppm-unfocused": dict(method="ppm", focus_photons=False),
    "a60-exact-unfocused": dict(method="amcmcppm", target_acceptance=0.60, mutation="exact",
                                focus_photons=False),
}
# The references' method: uncorrected, as all references made before the correction.
REFERENCE_METHOD = "a60-exact-uncorrected"
DEFAULT_METHODS = ("ppm", "original", "a60", "a60-paper", "a60-exact")
REFERENCE_RADIUS = 0.25     # the references' initial radius, in units of the runs' (module docstring)
SCENES = ("glass_ceiling_room", "hole_mirror_glass", "small_view")
# The seed paper's Table 1 (time saved by LM@60 % over plain@60 % to reach plain@60 %'s error at
# 600 s; time saved over the original at 23.4 %) and its visible fractions of uniform samples.
PAPER = {"glass_ceiling_room": (0.30, 0.55, 0.00022), "hole_mirror_glass": (0.00, 0.36, 0.24),
         "small_view": (0.15, 0.83, 0.00014)}


def git_commit():
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


# --------------------------------------------------------------------------- one run (subprocess)
def run_one(scene_name, resolution, method, seed, time_limit, out_path, radius_scale=1.0, photons=None):
    from core import RenderSettings, render
    from core.testing.scenes import BUILTIN

    scene = BUILTIN[scene_name](resolution=tuple(resolution))
    base = RenderSettings()
    kw = dict(METHODS[method], seed=seed, passes=0, time_limit=time_limit, workers=1,
              initial_radius_px=base.initial_radius_px * radius_scale)
    if photons:
        kw["photons_per_pass"] = photons
    images, stats = [], []

    def keep(result):
        images.append(result.image.copy())
        stats.append(result.stats[-1])

    result = render(scene, RenderSettings(**kw), on_iteration=keep)
    np.savez_compressed(out_path, images=np.array(images, np.float32),
                        elapsed=np.array([s["elapsed_s"] for s in stats]),
                        stats=json.dumps(stats), warnings=json.dumps(result.warnings))


def launch(args_list):
    cmd = [sys.executable, os.path.abspath(__file__), "--run-one", json.dumps(args_list)]
    subprocess.run(cmd, check=True)


# --------------------------------------------------------------------------------------- reference
def reference_path(scene, resolution):
    return os.path.join(ROOT, "benchmarks", "references", f"{scene}_{resolution[0]}x{resolution[1]}.npz")


def make_reference(scene, resolution, seconds, jobs, tmp, radius_scale=REFERENCE_RADIUS):
    """Two independent long runs (seeds 1001/1002, both at ``radius_scale`` r0); their mean is
    the reference."""
    halves = [(scene, resolution, REFERENCE_METHOD, seed, seconds, os.path.join(tmp, f"{scene}_ref{h}.npz"),
               radius_scale) for h, seed in (("A", 1001), ("B", 1002))]
    t0 = time.time()
    with ThreadPoolExecutor(max_workers=jobs) as ex:
        list(ex.map(launch, halves))
    a = np.load(halves[0][5])
    b = np.load(halves[1][5])
    img_a, img_b = a["images"][-1][..., :3], b["images"][-1][..., :3]
    split_half = float(np.sqrt(np.mean((img_a - img_b) ** 2)) / np.sqrt(2))
    meta = dict(scene=scene, resolution=list(resolution), method=REFERENCE_METHOD, seconds_per_half=seconds,
                passes=[len(a["elapsed"]), len(b["elapsed"])], seeds=[1001, 1002],
                radius_scales=[radius_scale, radius_scale],
                edge_coverage=METHODS[REFERENCE_METHOD].get("edge_coverage", True),
                split_half_rmse=split_half, mean=float(0.5 * (img_a + img_b).mean()), commit=git_commit(),
                machine=f"{platform.node()} {platform.processor()} {os.cpu_count()} cpus",
                wall_s=time.time() - t0, date=time.strftime("%Y-%m-%d %H:%M:%S"))
    path = reference_path(scene, resolution)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    np.savez_compressed(path, image=(0.5 * (img_a + img_b)).astype(np.float32), half_a=img_a.astype(np.float32),
                        half_b=img_b.astype(np.float32), meta=json.dumps(meta))
    return meta


# ----------------------------------------------------------------------------------------- metrics
def errors(images, ref, ref_var):
    """RMSE and relMSE of every image, and both corrected for the reference's noise ``ref_var``."""
    d = images[..., :3] - ref[None]
    sq = d * d
    w = 1.0 / (ref[None] ** 2 + 0.01)
    rmse = np.sqrt(np.mean(sq, axis=(1, 2, 3)))
    relmse = np.mean(sq * w, axis=(1, 2, 3))
    rmse_c = np.sqrt(np.maximum(np.mean(sq - ref_var[None], axis=(1, 2, 3)), 1e-30))
    relmse_c = np.maximum(np.mean((sq - ref_var[None]) * w, axis=(1, 2, 3)), 1e-30)
    return rmse, relmse, rmse_c, relmse_c


def at_checkpoints(elapsed, values, checkpoints):
    """Value of the last image finished by each checkpoint time (nan before the first)."""
    idx = np.searchsorted(elapsed, checkpoints, side="right") - 1
    return np.where(idx >= 0, values[np.maximum(idx, 0)], np.nan)


def time_to_reach(elapsed, values, target):
    """First time after which the error stays below ``target`` (log-log interpolation)."""
    above = np.flatnonzero(values > target)
    if len(above) == 0:
        return float(elapsed[0])
    k = above[-1]
    if k + 1 >= len(values):
        return float("inf")
    t0, t1, e0, e1 = elapsed[k], elapsed[k + 1], values[k], values[k + 1]
    f = (np.log(e0) - np.log(target)) / max(np.log(e0) - np.log(e1), 1e-12)
    return float(np.exp(np.log(t0) + f * (np.log(t1) - np.log(t0))))


def _time_cell(method, d, key):
    """A time-to-error table cell; PPM's own row is the baseline (its T-error is defined by it)."""
    if method == "ppm" and key == "time_to_ppm_t":
        return "(baseline)"
    return f"{d.get(key, float('nan')):.3g} s"


def slope(elapsed, values):
    """Least-squares slope of log error vs log time over the last decade of the run."""
    sel = elapsed >= elapsed[-1] / 10
    if sel.sum() < 3:
        return float("nan")
    return float(np.polyfit(np.log(elapsed[sel]), np.log(values[sel]), 1)[0])


# ------------------------------------------------------------------------------------------ report
def analyse(scene, runs, ref, ref_var, ref_meta, time_limit, methods):
    """Per method: curves at checkpoints (median, min, max over seeds), time-to-error, slopes.

    Curves and the time-to-error table use the corrected relMSE (``errors``)."""
    checkpoints = time_limit / 2.0 ** np.arange(8)[::-1]
    out = {"checkpoints": checkpoints.tolist(), "methods": {}, "reference": ref_meta}
    for m in methods:
        curves, per_run = [], []
        for path in runs[m]:
            z = np.load(path)
            rmse, relmse, rmse_c, relmse_c = errors(z["images"], ref, ref_var)
            stats = json.loads(str(z["stats"]))
            curves.append(at_checkpoints(z["elapsed"], relmse_c, checkpoints))
            per_run.append(dict(elapsed=z["elapsed"], rmse=rmse, relmse=relmse, rmse_c=rmse_c,
                                err=relmse_c, stats=stats))
        curves = np.array(curves)
        last = [r["stats"][-1] for r in per_run]
        book = [np.median([s.get("bookkeeping_share", 0.0) for s in r["stats"]]) for r in per_run]
        with warnings.catch_warnings():  # checkpoints before any run's first pass are all NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            median, lo, hi = (np.nanmedian(curves, axis=0), np.nanmin(curves, axis=0),
                              np.nanmax(curves, axis=0))
        out["methods"][m] = dict(
            median=median.tolist(), min=lo.tolist(), max=hi.tolist(),
            final_rmse=float(np.median([r["rmse"][-1] for r in per_run])),
            final_relmse=float(np.median([r["relmse"][-1] for r in per_run])),
            final_rmse_c=float(np.median([r["rmse_c"][-1] for r in per_run])),
            final_err=float(np.median([r["err"][-1] for r in per_run])),
            slope=float(np.median([slope(r["elapsed"], r["err"]) for r in per_run])),
            passes=float(np.median([len(r["elapsed"]) for r in per_run])),
            visible_fraction=float(np.median([s["visible_fraction"] for s in last])),
            acceptance=float(np.median([s["cumulative_acceptance_rate"] for s in last])),
            mutation_size=float(np.median([s["mutation_size"] for s in last])),
            bookkeeping_share=float(np.median(book)),
            _runs=per_run)
    # Time to reach PPM's error at T/10 and at T (per seed, then the median).
    for label, t_target in (("t10", time_limit / 10), ("t", time_limit)):
        ppm_runs = out["methods"]["ppm"]["_runs"] if "ppm" in out["methods"] else None
        if ppm_runs is None:
            break
        target = float(np.median([at_checkpoints(r["elapsed"], r["err"], np.array([t_target]))[0]
                                  for r in ppm_runs]))
        out[f"ppm_error_at_{label}"] = target
        for m, d in out["methods"].items():
            d[f"time_to_ppm_{label}"] = float(np.median([time_to_reach(r["elapsed"], r["err"], target)
                                                        for r in d["_runs"]]))
    # The paper's comparisons: LM@60 vs plain@60 (time to reach plain@60's final error) and
    # LM@60 vs the original at the end.
    for lm in ("a60-paper", "a60-exact"):
        if lm in out["methods"] and "a60" in out["methods"]:
            target = out["methods"]["a60"]["final_err"]
            t_lm = np.median([time_to_reach(r["elapsed"], r["err"], target)
                              for r in out["methods"][lm]["_runs"]])
            out[f"{lm}_time_cut_vs_a60"] = float(1 - t_lm / time_limit)
        if lm in out["methods"] and "original" in out["methods"]:
            target = out["methods"]["original"]["final_err"]
            t_lm = np.median([time_to_reach(r["elapsed"], r["err"], target)
                              for r in out["methods"][lm]["_runs"]])
            out[f"{lm}_time_cut_vs_original"] = float(1 - t_lm / time_limit)
    return out


def plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(results), figsize=(5.5 * len(results), 4.2), squeeze=False)
    for ax, (scene, res) in zip(axes[0], results.items()):
        t = np.array(res["checkpoints"])
        for m, d in res["methods"].items():
            med = np.array(d["median"])
            ax.loglog(t, med, marker="o", ms=3, label=f"{m} (slope {d['slope']:.2f})")
            ax.fill_between(t, d["min"], d["max"], alpha=0.15)
        ax.set_title(scene)
        ax.set_xlabel("render time (s)")
        ax.set_ylabel("relMSE, corrected for the reference's noise")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _pct(x):
    return "not within the run" if not np.isfinite(x) else f"{x:+.0%}"


def report(results, args, path):
    lines = [f"# Error versus time ({args.resolution[0]}x{args.resolution[1]}, {args.time:g} s per run, "
             f"{args.seeds} seeds, {args.jobs} runs at a time, one worker each)", "",
             f"Commit {git_commit()[:10]}, {platform.node()}, {os.cpu_count()} cpus, "
             f"{time.strftime('%Y-%m-%d %H:%M')}.", ""]
    for scene, res in results.items():
        ref = res["reference"]
        lines += [f"## {scene}", "",
                  f"Reference: {ref['method']}, 2 x {ref['seconds_per_half']:g} s, passes {ref['passes']}, "
                  f"radii {' and '.join(f'{x:g}' for x in ref['radius_scales'])} of the runs', "
                  f"split-half RMSE {ref['split_half_rmse']:.3g} (commit {ref['commit'][:10]}).", ""]
        smallest = min(d["final_rmse"] for d in res["methods"].values())
        lines += [f"The reference's split-half RMSE is {ref['split_half_rmse'] / smallest:.2f} of the smallest "
                  "raw RMSE below; the corrected columns remove its noise (module docstring).", ""]
        lines += ["| method | RMSE at T | corrected RMSE | corrected relMSE | slope (relMSE) | "
                  "time to PPM's T/10 relMSE | time to PPM's T relMSE | visible fraction | acceptance | theta "
                  "| bookkeeping share | passes |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for m, d in res["methods"].items():
            lines.append(f"| {m} | {d['final_rmse']:.4g} | {d['final_rmse_c']:.4g} | {d['final_err']:.4g} | "
                         f"{d['slope']:.2f} | "
                         f"{_time_cell(m, d, 'time_to_ppm_t10')} | {_time_cell(m, d, 'time_to_ppm_t')} | "
                         f"{d['visible_fraction']:.3g} | {d['acceptance']:.3f} | {d['mutation_size']:.3g} | "
                         f"{d['bookkeeping_share']:.2f} | {d['passes']:.0f} |")
        paper = PAPER.get(scene)
        lines += [""]
        for lm in ("a60-paper", "a60-exact"):
            a = res.get(f"{lm}_time_cut_vs_a60")
            b = res.get(f"{lm}_time_cut_vs_original")
            if a is not None:
                lines.append(f"- {lm}: time saved to reach a60's final error {_pct(a)} (paper {paper[0]:.0%}); "
                             f"to reach the original's final error {_pct(b)} (paper {paper[1]:.0%}).")
        for m in ("a60-paper", "a60-exact"):
            if m in res["methods"] and "ppm" in res["methods"]:
                t = res["methods"][m]["time_to_ppm_t"]
                lines.append(f"- {m} reaches PPM's {args.time:g}-second relMSE in {t:.3g} s "
                             f"({t / args.time:.2f} of the time).")
        lines.append("")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run-one", help=argparse.SUPPRESS)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    ap.add_argument("--methods", nargs="+", default=[m for m in METHODS if m in DEFAULT_METHODS],
                    choices=list(METHODS))
    ap.add_argument("--resolution", type=int, nargs=2, default=(64, 48),
                    help="the committed references in benchmarks/references are 64x48")
    ap.add_argument("--time", type=float, default=60.0, help="seconds per run")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=0, help="seeds first-seed .. first-seed + seeds - 1")
    ap.add_argument("--jobs", type=int, default=2, help="runs at the same time")
    ap.add_argument("--reference-time", type=float, default=1200.0, help="seconds per reference half")
    ap.add_argument("--reference-radius", type=float, default=REFERENCE_RADIUS,
                    help="the reference's initial radius over the runs' (both halves)")
    ap.add_argument("--make-reference", nargs="*", metavar="SCENE",
                    help="(re)compute the references of these scenes (none named: of every scene)")
    ap.add_argument("--photons-per-pass", type=int, default=None)
    ap.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "error_vs_time"))
    ap.add_argument("--quick", action="store_true", help="tiny smoke run (seconds, not minutes)")
    ap.add_argument("--analyse-only", action="store_true",
                    help="no runs: analyse the runs saved in --out (e.g. after --make-reference)")
    args = ap.parse_args()
    if args.run_one:
        run_one(*json.loads(args.run_one))
        return
    if args.quick:
        args.resolution, args.time, args.seeds, args.reference_time = (32, 24), 4.0, 2, 8.0
        args.out = os.path.join(args.out, "quick")
    os.makedirs(args.out, exist_ok=True)
    results = {}
    for scene in args.scenes:
        ref_path = reference_path(scene, args.resolution)
        if args.quick:
            ref_path = os.path.join(args.out, f"{scene}_reference.npz")
        remake = args.make_reference is not None and (not args.make_reference or scene in args.make_reference)
        if remake or not os.path.exists(ref_path):
            print(f"{scene}: reference, 2 x {args.reference_time:g} s ...", flush=True)
            meta = make_reference(scene, args.resolution, args.reference_time, args.jobs, args.out,
                                  args.reference_radius)
            if args.quick:
                os.replace(reference_path(scene, args.resolution), ref_path)
            print(f"  split-half RMSE {meta['split_half_rmse']:.4g}", flush=True)
        z = np.load(ref_path)
        ref, ref_meta = z["image"], json.loads(str(z["meta"]))
        ref_var = (z["half_a"] - z["half_b"]) ** 2 / 4 if "half_a" in z.files else np.zeros_like(ref)
        jobs, runs = [], {m: [] for m in args.methods}
        for m in args.methods:
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                path = os.path.join(args.out, f"{scene}_{m}_s{seed}.npz")
                runs[m].append(path)
                jobs.append((scene, list(args.resolution), m, seed, args.time, path, 1.0,
                             args.photons_per_pass))
        if args.analyse_only:
            missing = [j[5] for j in jobs if not os.path.exists(j[5])]
            if missing:
                sys.exit(f"--analyse-only: no saved run {missing[0]} (run without it first)")
        else:
            print(f"{scene}: {len(jobs)} runs of {args.time:g} s, {args.jobs} at a time ...", flush=True)
            with ThreadPoolExecutor(max_workers=args.jobs) as ex:
                list(ex.map(launch, jobs))
        results[scene] = analyse(scene, runs, ref, ref_var, ref_meta, args.time, args.methods)
    plot(results, os.path.join(args.out, "curves.png"))
    text = report(results, args, os.path.join(args.out, "report.md"))
    for res in results.values():
        for d in res["methods"].values():
            d.pop("_runs", None)
    with open(os.path.join(args.out, "summary.json"), "w") as f:
        json.dump(results, f, indent=1)
    print(text)


if __name__ == "__main__":
    main()
