"""Random-scene brightness parity: the mean brightness of our engine's image over Cycles', on random rooms.

A case is a random room drawn from its seed (``random_parity_scenes.py``): open (a floor, back and left
walls; lit also by a sun, a world colour or a sky texture) or closed (four walls and a ceiling),
with one to four objects (cube, sphere, cylinder, standing plane) of random materials (diffuse,
Principled with coat, sheen, specular level, subsurface or metal; glossy, translucent, emission;
a mix or add of two; checker or noise textures) and one to three lights (point, spot, area of every
shape and spread, an emissive panel).  Each engine renders it twice, with two seeds, every render
its own ``bpy`` process (:func:`render_child`):

    Cycles  1024 samples a pixel on one thread, no adaptive sampling, clamping, Filter Glossy and
            denoising off, caustics on, bounce limits 8 (volume 0), light tree on
    ours    16 passes of 100,000 photons, one worker, 4096 chains, initial radius 1.5 pixels,
            Cycles' light paths (the same limits)

and :func:`compare` gives the ratio of the means ours / Cycles (overall and per channel) and its
noise: for each engine the larger of half its two runs' difference in mean and the standard
error from the 4 x 4 image blocks' run-to-run differences, relative, the two added in quadrature.
A case is flagged when the ratio is off 1 by more than 0.03 + 3 noise (or a channel's by more than
0.04 + 4.5 noise); a block lit above a quarter of the mean when its ratio is off by more than 0.08
+ 3 times its own noise.  The summary ends with the median and the 5th-95th percentiles of the
cases' ratios.

The glass family (``--family glass``, cases named glass<seed>; ``random_glass_spec``) has one to
three transmissive objects (Glass, Principled transmission, Refraction, a Mix of glass and
diffuse; spheres, cubes, cylinders, thin panes; sometimes an absorbing liquid inside, sometimes a
volume-only cube of Volume Scatter or Principled Volume) and lights Cycles reaches through smooth
glass (area lights of size 0.4 or more, emissive panels, suns of 5 degrees or more, a world
colour); Cycles' limits are the spec's ``light_paths`` (Total, Glossy and Transmission 16, Diffuse
8, Volume 8 with a volume, Transparent 16; ours takes Cycles') and it renders 2048 samples.

    python benchmarks/random_parity.py --start 100 --count 40
    python benchmarks/random_parity.py --family glass --start 500 --count 30
    python benchmarks/random_parity.py --spec benchmarks/results/random_parity/runs/case115/spec.json
    python benchmarks/random_parity.py --quick                 # smoke run: one case, 16 x 12, seconds

writes ``benchmarks/results/random_parity/``: results.jsonl (one line a case: its spec and the
comparison) and runs/<case>/ (spec.json, cycles_<seed>.exr, ours_<seed>.exr).  ``--spec`` renders
spec files (a case's spec.json, which may be edited; named by their file names) instead of random
cases: ``room.keep_walls`` (the open room's walls to keep, of "Back" and "Left") and
``ours_settings`` (our settings to change, e.g. {"method": "ppm"}) help to find which part of a
scene a difference comes from.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from fuzz_scenes import load_addon
from random_parity_scenes import FAMILIES, build, describe

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLOCKS = 4                  # the image is compared in BLOCKS x BLOCKS blocks
RESULT_PREFIX = "RENDERED "  # a render process's last line: this and a JSON object


# ------------------------------------------------------------------------------ one render (child)
def set_light_paths(scene, spec):
    """Cycles' bounce limits of a case (ours takes them): 8 (volume 0), or the spec's ``light_paths``."""
    c = scene.cycles
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 8
    c.transparent_max_bounces = 8
    c.volume_bounces = 0
    for key, value in spec.get("light_paths", {}).items():     # (the glass family's limits)
        setattr(c, key, value)


def set_ours(scene, job):
    """Our settings of a case's render: ``job``'s seed, passes, photons, chains, initial radius, one
    worker, Cycles' light paths, then the spec's ``ours_settings``."""
    a = scene.amcmcppm
    a.light_paths_from_cycles = True
    a.workers = 1
    a.seed = job["seed"]
    a.time_limit = 0.0
    a.passes = job["passes"]
    a.photons_per_pass = job["photons"]
    a.chains = job["chains"]
    a.initial_radius_px = job["initial_radius"]
    for key, value in job["spec"].get("ours_settings", {}).items():
        setattr(a, key, value)


def render_child(job):
    """Render ``job["spec"]`` with ``job["engine"]`` ("cycles" or "ours") into ``job["exr"]``; print
    the render's wall time on a last line."""
    sys.path.insert(0, os.path.join(ROOT, "tests", "addon"))
    load_addon()
    import blender_scenes as bs
    scene = build(job["spec"], job["resolution"])
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 1
    c = scene.cycles
    c.device = "CPU"
    c.seed = job["seed"]
    c.use_adaptive_sampling = False
    c.use_denoising = False
    set_light_paths(scene, job["spec"])
    c.light_sampling_threshold = 0.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = c.caustics_refractive = True
    c.use_light_tree = True
    c.samples = job["spp"]
    set_ours(scene, job)
    scene.render.engine = "CYCLES" if job["engine"] == "cycles" else "AMCMCPPM"
    t0 = time.time()
    bs.render_exr(job["exr"], scene)
    print(RESULT_PREFIX + json.dumps({"seconds": round(time.time() - t0, 2)}), flush=True)


# ------------------------------------------------------------------------------ comparison
def read_rgb(path):
    """(H, W, 3) float64 linear RGB of an EXR."""
    import OpenEXR
    with OpenEXR.File(str(path)) as f:
        return np.asarray(f.channels()["RGBA"].pixels, np.float64)[..., :3]


def render(job, timeout):
    """Run :func:`render_child` in a new process; (image, seconds, warning lines)."""
    p = subprocess.run([sys.executable, os.path.abspath(__file__), "--child", json.dumps(job)],
                       capture_output=True, text=True, timeout=timeout)
    results = [x for x in p.stdout.splitlines() if x.startswith(RESULT_PREFIX)]
    if p.returncode or not results:
        raise RuntimeError(f"{job['engine']} failed: {p.stdout[-2000:]} {p.stderr[-2000:]}")
    warnings = [x for x in (p.stdout + p.stderr).splitlines()
                if "arning" in x or "Error" in x or "noted" in x.lower()]
    return read_rgb(job["exr"]), json.loads(results[-1][len(RESULT_PREFIX):])["seconds"], warnings


def block_means(img):
    """(BLOCKS, BLOCKS, 3) means of the image's blocks (the last rows and columns left out when the
    size is not a multiple)."""
    h, w = img.shape[0] // BLOCKS, img.shape[1] // BLOCKS
    return img[:h * BLOCKS, :w * BLOCKS].reshape(BLOCKS, h, BLOCKS, w, 3).mean(axis=(1, 3))


def mean_noise(a, b):
    """Standard error of the mean of images ``a`` and ``b`` (two runs): the larger of half their
    means' difference (one degree of freedom) and the estimate from their blocks' differences."""
    from_means = abs(a.mean() - b.mean()) / 2
    d = block_means(a).mean(axis=2) - block_means(b).mean(axis=2)
    from_blocks = np.sqrt((d ** 2).mean() / d.size) / 2
    return max(from_means, from_blocks)


def compare(c1, c2, o1, o2):
    """Ours (o1, o2) against Cycles (c1, c2), two runs each: ratios, noise and flags (see above)."""
    c, o = (c1 + c2) / 2, (o1 + o2) / 2
    mc, mo = c.mean(), o.mean()
    res = {"mean_c": mc, "mean_o": mo, "ratio": mo / mc,
           "ratio_ch": list(o.mean(axis=(0, 1)) / np.maximum(c.mean(axis=(0, 1)), 1e-9)),
           "ratio_runs": [o1.mean() / c1.mean(), o2.mean() / c2.mean()],
           "noise_c": mean_noise(c1, c2) / mc, "noise_o": mean_noise(o1, o2) / mo}
    res["noise"] = float(np.hypot(res["noise_c"], res["noise_o"]))
    bc, bo = block_means(c).mean(axis=2), block_means(o).mean(axis=2)
    dbc = np.abs(block_means(c1).mean(axis=2) - block_means(c2).mean(axis=2)) / 2
    dbo = np.abs(block_means(o1).mean(axis=2) - block_means(o2).mean(axis=2)) / 2
    block_ratio = bo / np.maximum(bc, 1e-9)
    block_noise = np.hypot(dbc / np.maximum(bc, 1e-9), dbo / np.maximum(bo, 1e-9))
    lit = bc > 0.25 * mc
    res["block_ratio"] = np.round(block_ratio, 3).tolist()
    res["block_noise"] = np.round(block_noise, 3).tolist()
    off = np.abs(block_ratio - 1) > 0.08 + 3 * np.maximum(block_noise, 0.01)
    res["bad_blocks"] = int((lit & off).sum())
    res["flag_mean"] = bool(abs(res["ratio"] - 1) > 0.03 + 3 * res["noise"])
    res["flag_channel"] = bool(max(abs(r - 1) for r in res["ratio_ch"]) > 0.04 + 3 * res["noise"] * 1.5)
    return {k: float(v) if isinstance(v, np.floating) else v for k, v in res.items()}


def run_case(spec, tag, args):
    """Render ``spec`` with both engines and both seeds into out/runs/<tag>/ and compare."""
    d = os.path.join(args.out, "runs", tag)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "spec.json"), "w") as f:
        json.dump(spec, f, indent=1)
    images, seconds, warnings = {}, {"cycles": 0.0, "ours": 0.0}, set()
    for engine in ("cycles", "ours"):
        for seed in args.seeds:
            job = {"spec": spec, "engine": engine, "seed": seed, "resolution": args.resolution,
                   "spp": args.spp or (2048 if spec.get("family") == "glass" else 1024),
                   "passes": args.passes, "photons": args.photons, "chains": args.chains,
                   "initial_radius": args.initial_radius, "exr": os.path.join(d, f"{engine}_{seed}.exr")}
            images[engine, seed], t, w = render(job, args.timeout)
            seconds[engine] += t
            warnings.update(w)
    s1, s2 = args.seeds
    res = compare(images["cycles", s1], images["cycles", s2], images["ours", s1], images["ours", s2])
    res.update(tag=tag, desc=describe(spec), time_c=seconds["cycles"], time_o=seconds["ours"],
               warnings=sorted(warnings))
    return res


def case_line(res):
    if "error" in res:
        return f"{res['tag']} ERROR {res['error'][-300:]}"
    flags = "".join(f" FLAG-{k}" for k in ("mean", "channel") if res[f"flag_{k}"])
    return (f"{res['tag']} ratio {res['ratio']:.4f} +- {res['noise']:.4f} ch {np.round(res['ratio_ch'], 3)} "
            f"flagged blocks {res['bad_blocks']}/{BLOCKS * BLOCKS}{flags} "
            f"t {res['time_c']:.0f}/{res['time_o']:.0f}s | {res['desc']}")


def print_summary(results, out):
    ratios = np.array([r["ratio"] for r in results if "error" not in r])
    errors = [r["tag"] for r in results if "error" in r]
    flagged = [r["tag"] for r in results if "error" not in r and (r["flag_mean"] or r["flag_channel"])]
    print(f"\n{len(results)} cases, {len(errors)} failed to render"
          + (f" ({', '.join(errors)})" if errors else ""))
    if len(ratios):
        p5, p50, p95 = np.percentile(ratios, [5, 50, 95])
        print(f"ratio ours / Cycles: median {p50:.4f}, 5th-95th percentile {p5:.4f} .. {p95:.4f} "
              f"({len(ratios)} cases)")
    print(f"flagged: {len(flagged)}" + (f" ({', '.join(flagged)})" if flagged else ""))
    print(f"results: {os.path.join(out, 'results.jsonl')}; images: {os.path.join(out, 'runs')}/<case>/")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--start", type=int, default=0, help="first case (its seed)")
    ap.add_argument("--count", type=int, default=10, help="cases start .. start + count - 1")
    ap.add_argument("--spec", nargs="+", metavar="FILE",
                    help="render these spec files (a case's recorded spec) instead of random cases")
    ap.add_argument("--resolution", type=int, nargs=2, default=(64, 48), metavar=("W", "H"))
    ap.add_argument("--seeds", type=int, nargs=2, default=(1, 2), metavar=("A", "B"),
                    help="the two seeds of each engine")
    ap.add_argument("--family", choices=sorted(FAMILIES), default="rooms",
                    help="the random specs: rooms (random_spec) or glass (random_glass_spec)")
    ap.add_argument("--spp", type=int, default=0,
                    help="Cycles' samples a pixel (default: 1024; 2048 for a glass spec)")
    ap.add_argument("--passes", type=int, default=16, help="our passes")
    ap.add_argument("--photons", type=int, default=100_000, help="our photons a pass")
    ap.add_argument("--chains", type=int, default=4096, help="our Markov chains")
    ap.add_argument("--initial-radius", type=float, default=1.5, help="our initial radius in pixels")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds a render may take")
    ap.add_argument("--deadline", type=float, default=0.0, help="start no case after this many seconds")
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: one case, 16x12, 16 samples, 2 passes of 10,000 photons, 256 chains")
    ap.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "random_parity"),
                    help="folder for results.jsonl and runs/ (default: %(default)s)")
    args = ap.parse_args()
    if args.child:
        render_child(json.loads(args.child))
        return
    if args.quick:
        args.count, args.resolution, args.spp = 1, (16, 12), 16
        args.passes, args.photons, args.chains = 2, 10_000, 256
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    if args.spec:
        cases = []
        for path in args.spec:
            with open(path) as f:
                cases.append((os.path.splitext(os.path.basename(path))[0], json.load(f)))
    else:
        seeds = range(args.start, args.start + args.count)
        prefix = "case" if args.family == "rooms" else args.family
        cases = [(f"{prefix}{seed:03d}", FAMILIES[args.family](seed)) for seed in seeds]
    t0 = time.time()
    results = []
    for tag, spec in cases:
        if args.deadline and time.time() - t0 > args.deadline:
            print("deadline reached", flush=True)
            break
        try:
            res = run_case(spec, tag, args)
        except (RuntimeError, subprocess.TimeoutExpired) as e:
            res = {"tag": tag, "desc": describe(spec), "error": str(e)[-1500:]}
        res["spec"] = spec
        with open(os.path.join(args.out, "results.jsonl"), "a") as f:
            f.write(json.dumps(res) + "\n")
        results.append(res)
        print(case_line(res), flush=True)
    print_summary(results, args.out)


if __name__ == "__main__":
    main()
