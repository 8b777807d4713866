"""Our engine against Cycles in error for the same time, on the sample .blend scenes.

The project's aim is to beat the renderers people use today where light takes hard paths, in
error for the same time.  ``error_vs_time.py`` compares our methods with each other on the core's
built-in scenes; this benchmark puts Cycles beside them on the sample .blend files, each render a
separate ``bpy`` process that opens the file, sets the resolution and renders with the machine's
cores (Cycles' threads fixed to ``--threads``, ours with as many workers):

    cycles           Cycles as an artist leaves it (the file's Cycles settings: adaptive sampling,
                     Filter Glossy 1, indirect clamping 10, light tree), path tracing on the CPU,
                     the time limit and no denoiser; adaptive sampling's noise threshold 1e-4, so
                     that it uses the whole time
    cycles-denoised  the same with Cycles' default denoiser (OpenImageDenoise with albedo and normal)
    cycles-mnee      ``cycles`` with Shadow Caustics (manifold next event estimation) on, as Cycles'
                     manual sets it up: refracting objects cast, the other meshes receive, every
                     light makes shadow caustics
    cycles-unclamped ``cycles`` with Clamping and Filter Glossy off, as the reference: its defaults
                     (indirect light clamped at 10) took 85 % of the glass-roofed room's light
    cycles-guided    ``cycles-unclamped`` with Path Guiding on (Intel's Open Path Guiding Library,
                     CPU only; its defaults: surface and volume guiding, 128 training samples)
    ours             our engine with the file's settings (AMCMCPPM by default)
    ours-denoised    ``ours`` with Denoising Data on and the compositor's Denoise node (the same
                     OpenImageDenoise, on our Denoising Albedo and Normal): what an artist can do
                     with our engine today
    ours-ppm         ours with uniform photons (SPPM)
    ours-sampled     ``ours`` with Direct Light "Light Samples" (core/direct.py): the light straight
                     from emitters from light samples and shadow rays, photons for the rest
    ours-random-jitter  ``ours`` with Pixel Jitter "Random" (each pass's camera rays at independent
                     points of their pixels, as before stop 59's stratified jitter)

Each run gets ``--time`` seconds (Cycles' Time Limit, which leaves out its scene synchronisation;
ours' Time Limit) and ours also saves its image at
an eighth, a quarter and half of it; Cycles is run again at a quarter of the time.  The wall time
of every render call is recorded and reported, and the curves put each image at it (ours' snapshots
at the core's elapsed time, which leaves out the export).

Errors are against two references, each the mean of two long halves with different seeds, stored
in ``benchmarks/references/versus_cycles/``: Cycles' (adaptive sampling, Filter Glossy and clamping
off, no denoiser: unbiased path tracing) and ours (uncorrected SPPM-style gathers at a quarter of the
initial radius, as ``error_vs_time.py``'s references; AMCMCPPM).  Where a path tracer cannot find the
light (a caustic of a small light seen through glass or in a mirror) Cycles' reference stays noisy
after any affordable time, and ours carries our engine's approximations; the report gives both,
and the ratios of the references' 8 x 8 pixel blocks beside those of each one's two halves say how
far they agree (:func:`block_ratios`).  relMSE = mean((I - R)^2 / (R^2 + 0.01)) over linear RGB,
corrected for the reference's noise by the halves' (A - B)^2 / 4 as in ``error_vs_time.py``; in
brackets, the same without the image's 0.1 % of pixels of largest error (:func:`trimmed_relmse`).

    python benchmarks/versus_cycles.py --scenes cornell_box glass_ceiling caustic_sds small_view \\
        --resolution 160 120 --time 60 --seeds 2 --reference-time 180

writes ``benchmarks/results/versus_cycles/`` (images, runs.jsonl: one record a run, report.md,
summary.json, curves.png, images.png); ``--analyse-only`` reports every run recorded there again
(e.g. after another invocation added ``--methods``).  ``--quick`` is a smoke run of a minute or two
at a tiny size.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from typing import NamedTuple

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from error_vs_time import errors, git_commit  # noqa: E402

METHODS = ("cycles", "cycles-denoised", "cycles-mnee", "cycles-unclamped", "cycles-guided", "ours",
           "ours-denoised", "ours-ppm", "ours-sampled", "ours-random-jitter")
REFERENCES = ("cycles", "ours")
REFERENCE_SEEDS = (1001, 1002)
OURS_REFERENCE_RADIUS = 0.25        # of the file's initial radius (error_vs_time.REFERENCE_RADIUS)
SNAPSHOT_FRACTIONS = (0.125, 0.25, 0.5)
CYCLES_FRACTIONS = (0.25,)          # Cycles' extra runs, as fractions of --time
CYCLES_MAX_SAMPLES = 1 << 24        # Cycles' largest sample count: the time limit decides
CYCLES_NOISE_THRESHOLD = 1e-4       # adaptive sampling's threshold in the runs (Cycles' default 0.01)


# ------------------------------------------------------------------------------ one render (child)
def child(spec):
    """Render ``spec`` (a dict, see :func:`render`) in this process with ``bpy``; print a JSON line
    with the render call's wall time."""
    import bpy

    from render import ensure_addon, set_output

    ensure_addon(bpy)
    bpy.ops.wm.open_mainfile(filepath=spec["blend"])
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x, r.resolution_y = spec["resolution"]
    r.resolution_percentage = 100
    r.use_border = False
    r.threads_mode = "FIXED"
    r.threads = spec["threads"]
    kind = spec["kind"]
    if kind.startswith("cycles"):
        r.engine = "CYCLES"
        c = scene.cycles
        c.device = "CPU"
        c.samples = CYCLES_MAX_SAMPLES
        c.time_limit = spec["time"]
        c.seed = spec["seed"]
        c.use_animated_seed = False
        c.use_denoising = kind == "cycles-denoised" and not spec["reference"]
        if kind == "cycles-mnee":
            shadow_caustics(bpy, scene)
        c.use_guiding = kind == "cycles-guided"         # (its surface and volume guiding on by default)
        if kind in ("cycles-unclamped", "cycles-guided") or spec["reference"]:
            c.blur_glossy = 0.0
            c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
        # Adaptive sampling stays on, but with a threshold low enough that it does not stop before
        # the time limit (the default 0.01 stopped a 48x36 Cornell box at 1.5 s of 4); the
        # reference samples every pixel alike.
        c.adaptive_threshold = CYCLES_NOISE_THRESHOLD
        c.use_adaptive_sampling = not spec["reference"]
    else:
        r.engine = "AMCMCPPM"
        p = scene.amcmcppm
        p.passes = 0
        p.time_limit = spec["time"]
        p.seed = spec["seed"]
        p.workers = spec["threads"]
        if kind == "ours-ppm":
            p.method = "ppm"
        if kind == "ours-sampled":
            p.direct_light = "sampled"
        if kind == "ours-random-jitter":
            p.pixel_jitter = "random"
        if spec["reference"]:
            p.initial_radius_px *= OURS_REFERENCE_RADIUS
            p.bias_correction = False
        p.stats_path = spec["out"] + ".stats.jsonl"         # the engine appends: start empty
        open(p.stats_path, "w").close()
        if kind == "ours-denoised":
            denoise_in_compositor(bpy, scene)
        if spec.get("snapshot_times"):
            p.snapshot_times = ",".join(f"{t:g}" for t in spec["snapshot_times"])
            p.snapshot_dir = spec["snapshot_dir"]
    set_output(scene, spec["out"])
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    print("RESULT " + json.dumps({"wall_s": time.perf_counter() - t0}), flush=True)


def _refracts(material):
    """Whether ``material``'s nodes hold a Glass or Refraction BSDF or a Principled BSDF with
    transmission (what Cycles' shadow caustics can refract through)."""
    if material is None or not material.use_nodes:
        return False
    for node in material.node_tree.nodes:
        if node.type in ("BSDF_GLASS", "BSDF_REFRACTION"):
            return True
        if node.type == "BSDF_PRINCIPLED" and (node.inputs["Transmission Weight"].is_linked
                                               or node.inputs["Transmission Weight"].default_value > 0):
            return True
    return False


def shadow_caustics(bpy, scene):
    """Cycles' Shadow Caustics (manifold next event estimation), set as its manual asks: objects of
    refracting materials cast them, every other mesh receives them, every light makes them.  A
    caster's faces are shaded smooth with edges sharper than 30 degrees kept sharp (Shade Auto
    Smooth: flat faces stay flat): Cycles' manifold walk rejects a caster without smooth normals
    (``kernel/integrator/mnee.h``), which left the flat-shaded glass pane's room black."""
    for ob in scene.objects:
        if ob.type == "MESH":
            caster = any(_refracts(slot.material) for slot in ob.material_slots)
            ob.cycles.is_caustics_caster = caster
            ob.cycles.is_caustics_receiver = not caster
            if caster and not all(poly.use_smooth for poly in ob.data.polygons):
                ob.data.polygons.foreach_set("use_smooth", [True] * len(ob.data.polygons))
                ob.data.set_sharp_from_angle(angle=math.radians(30.0))
        elif ob.type == "LIGHT":
            ob.data.cycles.is_caustics_light = True


def denoise_in_compositor(bpy, scene):
    """Denoising Data on and a compositor of Render Layers -> Denoise (Image, Denoising Normal,
    Denoising Albedo; the node's defaults) -> output."""
    bpy.context.view_layer.cycles.denoising_store_passes = True
    tree = bpy.data.node_groups.new("Denoise", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    layers = tree.nodes.new("CompositorNodeRLayers")
    denoise = tree.nodes.new("CompositorNodeDenoise")
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(layers.outputs["Image"], denoise.inputs["Image"])
    tree.links.new(layers.outputs["Denoising Normal"], denoise.inputs["Normal"])
    tree.links.new(layers.outputs["Denoising Albedo"], denoise.inputs["Albedo"])
    tree.links.new(denoise.outputs["Image"], out.inputs[0])
    scene.compositing_node_group = tree
    scene.render.use_compositing = True


def render(blend, kind, resolution, seed, seconds, out, threads, reference=False, snapshot_times=None,
           snapshot_dir=None):
    """Render in a fresh process; return the render call's wall time in seconds."""
    spec = dict(blend=blend, kind=kind, resolution=list(resolution), seed=seed, time=seconds, out=out,
                threads=threads, reference=reference, snapshot_times=snapshot_times,
                snapshot_dir=snapshot_dir)
    cmd = [sys.executable, os.path.abspath(__file__), "--child", json.dumps(spec)]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
    if done.returncode != 0 or not lines or not os.path.isfile(out):
        raise RuntimeError(f"{kind} on {blend} failed ({done.returncode}):\n{done.stdout[-2000:]}\n"
                           f"{done.stderr[-2000:]}")
    return json.loads(lines[-1][len("RESULT "):])["wall_s"]


def read_rgb(path):
    from core.imageio import read_exr

    return np.asarray(read_exr(path), np.float64)[..., :3]


# -------------------------------------------------------------------------------------- references
REFERENCE_DIR = os.path.join(ROOT, "benchmarks", "references", "versus_cycles")


def reference_path(scene, resolution, renderer, folder=REFERENCE_DIR):
    return os.path.join(folder, f"{scene}_{resolution[0]}x{resolution[1]}_{renderer}.npz")


def make_reference(scene, blend, resolution, renderer, seconds, threads, tmp, folder):
    """Two renders of ``seconds`` (seeds REFERENCE_SEEDS); their mean is the reference."""
    halves, walls = [], []
    for seed in REFERENCE_SEEDS:
        out = os.path.join(tmp, f"{scene}_ref_{renderer}_{seed}.exr")
        walls.append(render(blend, renderer, resolution, seed, seconds, out, threads, reference=True))
        halves.append(read_rgb(out))
    a, b = halves
    meta = dict(scene=scene, renderer=renderer, resolution=list(resolution), seconds_per_half=seconds,
                wall_s=walls, seeds=list(REFERENCE_SEEDS), threads=threads, mean=float(0.5 * (a + b).mean()),
                split_half_rmse=float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(2)), commit=git_commit(),
                machine=f"{platform.node()} {os.cpu_count()} cpus", date=time.strftime("%Y-%m-%d %H:%M:%S"))
    path = reference_path(scene, resolution, renderer, folder)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    np.savez_compressed(path, image=(0.5 * (a + b)).astype(np.float32), half_a=a.astype(np.float32),
                        half_b=b.astype(np.float32), meta=json.dumps(meta))
    return meta


class Reference(NamedTuple):
    """A stored reference: the mean of its halves, its per-pixel noise variance (A - B)^2 / 4
    (``error_vs_time.errors``' correction), its metadata and the halves themselves."""
    image: np.ndarray
    variance: np.ndarray
    meta: dict
    half_a: np.ndarray
    half_b: np.ndarray


def load_reference(scene, resolution, renderer, folder):
    z = np.load(reference_path(scene, resolution, renderer, folder))
    a, b = z["half_a"].astype(np.float64), z["half_b"].astype(np.float64)
    return Reference(0.5 * (a + b), 0.25 * (a - b) ** 2, json.loads(str(z["meta"])), a, b)


def relmse(images, ref):
    """(raw, corrected) relMSE of ``images`` (k, H, W, 3) against the Reference ``ref``."""
    _, raw, _, corrected = errors(np.asarray(images), ref.image, ref.variance)
    return raw, corrected


TRIM = 0.001    # the share of pixels with the largest error that the trimmed relMSE leaves out


def trimmed_relmse(image, ref):
    """The corrected relMSE of ``image`` (H, W, 3) over all but its TRIM share of pixels with the
    largest corrected error: a figure that one pixel (a firefly, or a caustic seen through glass in
    a mirror that neither renderer has converged on) cannot decide alone."""
    d = image - ref.image
    per_pixel = np.mean((d * d - ref.variance) / (ref.image ** 2 + 0.01), axis=2).ravel()
    keep = len(per_pixel) - int(np.ceil(TRIM * len(per_pixel)))
    return float(max(np.partition(per_pixel, keep - 1)[:keep].mean(), 1e-30))


def references_apart(refs):
    """Corrected relMSE of the two references against each other, weighted by Cycles' (the same
    estimator as the runs': their difference squared less both halves' variances)."""
    c, o = refs["cycles"], refs["ours"]
    w = 1.0 / (c.image ** 2 + 0.01)
    return float(max(np.mean(((o.image - c.image) ** 2 - c.variance - o.variance) * w), 1e-30))


BLOCK = 8       # pixels a side of the blocks the references are compared in


def block_ratios(refs):
    """The 5th and 95th percentiles of the ratio of the references' 8 x 8 block means (ours over
    Cycles'), and of each reference's two halves (A over B): where the first range lies within
    Cycles' own, the references differ by no more than Cycles' reference's noise.  (The per-pixel
    ``references_apart`` is not reliable where a reference is noisy: its weight 1 / (R^2 + 0.01)
    takes R from the noisy reference.)"""
    def blocks(x):
        h, w = (x.shape[0] // BLOCK) * BLOCK, (x.shape[1] // BLOCK) * BLOCK
        return x[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, -1).mean(axis=(1, 3, 4))

    def spread(num, den):
        return [float(v) for v in np.percentile(blocks(num) / np.maximum(blocks(den), 1e-9), [5, 95])]

    out = {"ours/cycles": spread(refs["ours"].image, refs["cycles"].image)}
    for name in REFERENCES:
        out[f"{name} A/B"] = spread(refs[name].half_a, refs[name].half_b)
    return out


# ------------------------------------------------------------------------------------------- runs
def run_scene(scene, blend, args, out_dir):
    """Render every method and seed, each run's record ({scene, method, seed, times, images: the
    image paths and the seconds at which each was had: a render call's wall time, ours' snapshots
    the core's elapsed time}) appended to ``out_dir``/runs.jsonl as it finishes (a record of the same scene,
    method and seed replaces an earlier one in :func:`load_runs`)."""
    runs = {m: [] for m in args.methods}
    for seed in range(1, args.seeds + 1):
        for method in args.methods:
            base = os.path.join(out_dir, f"{scene}_{method}_{seed}")
            if method.startswith("cycles"):
                points = []
                for frac in (*args.cycles_fractions, 1.0):
                    t = args.time * frac
                    out = f"{base}_{t:g}s.exr"
                    wall = render(blend, method, args.resolution, seed, t, out, args.threads)
                    points.append((wall, out))
                runs[method].append(dict(seed=seed, times=[p[0] for p in points],
                                         images=[p[1] for p in points]))
            else:
                snap_dir = base + "_snapshots"
                # (The snapshots are the raw image: a denoised run has its final point only.)
                times = [args.time * f for f in SNAPSHOT_FRACTIONS] if method != "ours-denoised" else None
                out = base + ".exr"
                wall = render(blend, method, args.resolution, seed, args.time, out, args.threads,
                              snapshot_times=times, snapshot_dir=snap_dir)
                snaps = _snapshots(snap_dir)
                runs[method].append(dict(seed=seed, times=[s[0] for s in snaps] + [wall],
                                         images=[s[1] for s in snaps] + [out]))
            with open(os.path.join(out_dir, "runs.jsonl"), "a") as f:
                f.write(json.dumps(dict(scene=scene, method=method, resolution=list(args.resolution),
                                        **runs[method][-1])) + "\n")
            print(f"  {scene} {method} seed {seed}: wall {runs[method][-1]['times'][-1]:.1f} s", flush=True)


def load_runs(out_dir, scene, resolution):
    """{method: [record by seed]} of ``scene`` at ``resolution`` in ``out_dir``/runs.jsonl, the
    methods in METHODS' order."""
    found = {}
    path = os.path.join(out_dir, "runs.jsonl")
    if os.path.isfile(path):
        with open(path) as f:
            for line in f:
                rec = json.loads(line)
                if rec["scene"] == scene and rec["resolution"] == list(resolution):
                    found[(rec["method"], rec["seed"])] = rec
    return {m: [found[k] for k in sorted(found) if k[0] == m]
            for m in METHODS if any(k[0] == m for k in found)}


def _snapshots(folder):
    """[(elapsed_s, path)] of the engine's snapshots in ``folder`` (its snapshots.jsonl)."""
    index = os.path.join(folder, "snapshots.jsonl")
    if not os.path.isfile(index):
        return []
    out = []
    with open(index) as f:
        for line in f:
            rec = json.loads(line)
            out.append((float(rec["elapsed_s"]), os.path.join(folder, rec["file"])))
    return out


def analyse(scene, runs, refs):
    """Errors of every run image against every reference: {method: {ref: {...}}}."""
    result = {}
    for method, seeds in runs.items():
        per_ref = {}
        for name, ref in refs.items():
            finals, curves, trimmed = [], [], []
            for run in seeds:
                imgs = np.stack([read_rgb(p) for p in run["images"]])
                raw, corr = relmse(imgs, ref)
                curves.append(dict(seed=run["seed"], times=run["times"], relmse=corr.tolist(),
                                   relmse_raw=raw.tolist()))
                finals.append(float(corr[-1]))
                trimmed.append(trimmed_relmse(imgs[-1], ref))
            per_ref[name] = dict(final=finals, median=float(np.median(finals)), curves=curves,
                                 trimmed=trimmed)
        means = [float(read_rgb(run["images"][-1]).mean()) for run in seeds]
        result[method] = dict(refs=per_ref, wall_s=[run["times"][-1] for run in seeds], image_mean=means,
                              passes=[_passes(run["images"][-1]) for run in seeds])
    return result


def _passes(image):
    """Passes our engine made for ``image`` (lines of its statistics file), or None (Cycles)."""
    path = image + ".stats.jsonl"
    if not os.path.isfile(path):
        return None
    with open(path) as f:
        return sum(1 for line in f if line.strip())


def plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(results)
    fig, axes = plt.subplots(len(REFERENCES), len(scenes), figsize=(4.2 * len(scenes), 3.6 * len(REFERENCES)),
                             squeeze=False)
    for j, scene in enumerate(scenes):
        for i, ref in enumerate(REFERENCES):
            ax = axes[i][j]
            for k, (method, d) in enumerate(results[scene]["methods"].items()):
                for c, curve in enumerate(d["refs"][ref]["curves"]):
                    ax.loglog(curve["times"], curve["relmse"], "o-", color=f"C{k}", alpha=0.8,
                              label=method if c == 0 else None)
            ax.set_title(f"{scene}: against {ref}'s reference", fontsize=9)
            ax.set_xlabel("seconds")
            ax.set_ylabel("relMSE (corrected)")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def image_grid(grids, path):
    """The references and each method's final image of seed 1, scene by scene, tone-mapped alike
    (sRGB, exposed so that Cycles' reference has a mean of 0.18)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from core.imageio import to_display

    columns = max(len(REFERENCES) + len(runs) for _, runs in grids.values())
    fig, axes = plt.subplots(len(grids), columns, figsize=(2.2 * columns, 1.9 * len(grids)), squeeze=False)
    for i, (scene, (refs, runs)) in enumerate(grids.items()):
        exposure = np.log2(0.18 / max(float(refs["cycles"].image.mean()), 1e-6))
        panels = [(f"{n} reference", refs[n].image) for n in REFERENCES]
        panels += [(m, read_rgb(recs[0]["images"][-1])) for m, recs in runs.items() if recs]
        for j in range(columns):
            ax = axes[i][j]
            ax.axis("off")
            if j < len(panels):
                title, img = panels[j]
                ax.imshow(to_display(img, exposure))
                ax.set_title(f"{scene}: {title}" if j == 0 else title, fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)


def report(results, args, path):
    seeds = max(len(d["wall_s"]) for r in results.values() for d in r["methods"].values())
    lines = [f"# Ours against Cycles: {args.resolution[0]}x{args.resolution[1]}, {args.time:g} s a run, "
             f"{seeds} seed(s), {args.threads} threads", "",
             f"commit {git_commit()}, {time.strftime('%Y-%m-%d %H:%M')}, {platform.node()}, "
             f"{os.cpu_count()} cpus", "",
             "Corrected relMSE at the end of the run, median over seeds [smallest, largest] (the median "
             f"without each image's {100 * TRIM:g} % of pixels of largest error); "
             "wall: the render call's seconds (median).", ""]
    for scene, r in results.items():
        lines += [f"## {scene}", "", "references: " + "; ".join(
            f"{n}: mean {m['mean']:.4g}, 2 x {m['seconds_per_half']:g} s, "
            f"split-half RMSE {m['split_half_rmse']:.3g}" for n, m in r["reference_meta"].items())
            + f"; apart (corrected relMSE) {r['references_apart']:.3g}", "",
            f"{BLOCK} x {BLOCK} block ratios, 5th-95th percentile: " + "; ".join(
                f"{n} {lo:.3f}-{hi:.3f}" for n, (lo, hi) in r["block_ratios"].items()), "",
            "| method | against Cycles' reference | against ours | image mean | wall s | passes |",
            "|---|---|---|---|---|---|"]
        for method, d in r["methods"].items():
            cells = []
            for ref in REFERENCES:
                f = d["refs"][ref]["final"]
                trimmed = np.median(d["refs"][ref]["trimmed"])
                cells.append(f"{np.median(f):.3g} [{min(f):.3g}, {max(f):.3g}] ({trimmed:.3g})")
            passes = [n for n in d["passes"] if n is not None]
            lines.append(f"| {method} | {cells[0]} | {cells[1]} | {np.median(d['image_mean']):.4g} | "
                         f"{np.median(d['wall_s']):.1f} | {int(np.median(passes)) if passes else ''} |")
        lines.append("")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--child", help=argparse.SUPPRESS)
    p.add_argument("--scenes", nargs="+",
                   default=["cornell_box", "glass_ceiling", "caustic_sds", "small_view"])
    p.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    p.add_argument("--resolution", type=int, nargs=2, default=(160, 120))
    p.add_argument("--time", type=float, default=60.0, help="seconds a run")
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    p.add_argument("--reference-time", type=float, default=180.0, help="seconds per reference half")
    p.add_argument("--make-reference", action="store_true", help="remake the references even if stored")
    p.add_argument("--cycles-fractions", type=float, nargs="*", default=list(CYCLES_FRACTIONS),
                   help="Cycles' extra runs, as fractions of --time (none: only the full time)")
    p.add_argument("--analyse-only", action="store_true",
                   help="render nothing: report every run recorded in --out's runs.jsonl")
    p.add_argument("--quick", action="store_true", help="smoke run: 48x36, 4 s, one seed, 8 s references "
                                                         "(kept in --out, not with the real ones)")
    p.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "versus_cycles"))
    args = p.parse_args()
    if args.child:
        child(json.loads(args.child))
        return
    if args.quick:
        args.resolution, args.time, args.seeds, args.reference_time = (48, 36), 4.0, 1, 8.0
        args.scenes = args.scenes[:1]
    ref_dir = os.path.join(args.out, "references") if args.quick else REFERENCE_DIR
    os.makedirs(args.out, exist_ok=True)
    tmp = os.path.join(args.out, "tmp")
    os.makedirs(tmp, exist_ok=True)
    results, grids = {}, {}
    for scene in args.scenes:
        blend = os.path.join(ROOT, "sample_blends", f"{scene}.blend")
        refs = {}
        for renderer in REFERENCES:
            stored = os.path.isfile(reference_path(scene, args.resolution, renderer, ref_dir))
            if args.make_reference or not stored:
                print(f"{scene}: {renderer}'s reference, 2 x {args.reference_time:g} s", flush=True)
                make_reference(scene, blend, args.resolution, renderer, args.reference_time, args.threads,
                               tmp, ref_dir)
            refs[renderer] = load_reference(scene, args.resolution, renderer, ref_dir)
        if not args.analyse_only:
            run_scene(scene, blend, args, args.out)
        runs = load_runs(args.out, scene, args.resolution)
        results[scene] = dict(methods=analyse(scene, runs, refs), references_apart=references_apart(refs),
                              block_ratios=block_ratios(refs),
                              reference_meta={n: r.meta for n, r in refs.items()})
        grids[scene] = (refs, runs)
        with open(os.path.join(args.out, "summary.json"), "w") as f:
            json.dump(dict(args={k: v for k, v in vars(args).items() if k != "child"}, results=results), f,
                      indent=1)
    print(report(results, args, os.path.join(args.out, "report.md")))
    plot(results, os.path.join(args.out, "curves.png"))
    image_grid(grids, os.path.join(args.out, "images.png"))


if __name__ == "__main__":
    main()
