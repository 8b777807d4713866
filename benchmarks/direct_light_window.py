"""Direct light from light samples where the emitter is seen through a small opening.

``core/direct.py``'s light samples (``RenderSettings.direct_light = "sampled"``) draw a direction
towards an emitter from each measurement point; where that emitter is a sky seen only through a
window, most of them meet a wall, while the photons' first vertices (the default, the paper's
method) land where the light gets in.  This renders a closed room of 4 x 4 x 2.5 m lit only by a
constant white sky through a square window of ``--window`` m in one wall (and a box on the floor),
with both, for the same time each, against a reference of uniform photons (PPM, a quarter of the
initial radius, ``--reference-time`` seconds with 2 workers):

    python benchmarks/direct_light_window.py --time 30 --seeds 3

and prints relMSE = mean((I - R)^2 / (R^2 + 0.01)) and MSE / mean(R)^2 for every run.  The
reference is the photons' method, so its own kernel bias (a sixteenth of a run's) counts against
the light samples alone.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def window_room(window=0.3, resolution=(64, 48)):
    from core import Camera, Lights, Materials, World
    from core.testing.scenes import MeshBuilder, _add_rotated_box, _room_with_hole
    m = MeshBuilder()
    _room_with_hole(m, 2.0, 2.5, (0.0, 1.6), window, 0)
    _add_rotated_box(m, (0.2, -0.4, 0.0), (0.7, 0.7, 0.7), 0.5, 1)
    mats = Materials.build([{"name": "wall", "diffuse": (0.7, 0.7, 0.7)},
                            {"name": "box", "diffuse": (0.6, 0.3, 0.2)}])
    cam = Camera.look_at((-1.8, -1.7, 1.6), (1.0, 0.6, 0.5), lens_mm=18.0, resolution=resolution)
    return m.build(mats, Lights.build([]), cam, World(color=np.float32([1.0, 1.0, 1.0])))


def run_one(kind, seed, seconds, out, window):
    """One render in this process: ``kind`` "reference", "photons" or "sampled"."""
    from core import RenderSettings, render
    base = RenderSettings()
    kw = (dict(method="ppm", initial_radius_px=0.25 * base.initial_radius_px, workers=2)
          if kind == "reference" else dict(direct_light=kind, workers=1))
    r = render(window_room(window), RenderSettings(seed=seed, passes=0, time_limit=seconds, **kw))
    np.save(out, r.image[..., :3])
    print(f"{kind} seed {seed}: {len(r.stats)} passes, direct light from {r.direct_light}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--time", type=float, default=30.0, help="seconds per run")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--reference-time", type=float, default=180.0)
    ap.add_argument("--window", type=float, default=0.3, help="the window's side in metres")
    ap.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "direct_light_window"))
    ap.add_argument("--run-one", nargs=3, metavar=("KIND", "SEED", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.run_one:
        kind, seed, out = a.run_one
        return run_one(kind, int(seed), a.reference_time if kind == "reference" else a.time, out, a.window)
    os.makedirs(a.out, exist_ok=True)

    def spawn(kind, seed):
        out = os.path.join(a.out, f"{kind}_{seed}.npy")
        cmd = [sys.executable, os.path.abspath(__file__), "--time", str(a.time), "--reference-time",
               str(a.reference_time), "--window", str(a.window), "--run-one", kind, str(seed), out]
        subprocess.run(cmd, check=True)
        return out

    ref = np.load(spawn("reference", 1000))
    # The two methods' runs of a seed side by side (one worker each on the 2 cores).
    with ThreadPoolExecutor(2) as pool:
        runs = {(k, s): pool.submit(spawn, k, s) for s in range(1, a.seeds + 1)
                for k in ("photons", "sampled")}
        images = {key: np.load(f.result()) for key, f in runs.items()}
    print(f"\nwindow {a.window} m, {a.time:g} s a run, reference {a.reference_time:g} s "
          f"(mean {ref.mean():.5f})")
    print("| direct light | relMSE per seed | MSE / mean(R)^2 per seed |\n|---|---|---|")
    for kind in ("photons", "sampled"):
        rel = [np.mean((images[kind, s] - ref) ** 2 / (ref ** 2 + 0.01)) for s in range(1, a.seeds + 1)]
        mse = [np.mean((images[kind, s] - ref) ** 2) / ref.mean() ** 2 for s in range(1, a.seeds + 1)]
        print(f"| {kind} | {', '.join(f'{x:.3g}' for x in rel)} | {', '.join(f'{x:.3g}' for x in mse)} |")


if __name__ == "__main__":
    main()
