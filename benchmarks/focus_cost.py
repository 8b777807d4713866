"""Photons from afar aimed at what the camera sees (``RenderSettings.focus_photons``), for the same time.

PPM's photons from the sun and the world start on the disc of the scene's bounding sphere; where
the camera sees a small part of a large scene, few of them land there.  The focus
(``core.lights.Focus``) starts half of them on the disc of a sphere around the first pass's points
instead.  This renders, for ``--time`` seconds each with one worker (``--jobs`` runs at a time):

    sky_over_floor    an open 40 m floor under a constant sky, 35 mm from 2 m up (64 x 48; closed
                      form: albedo times sky)
    sunlit_corner     a 600 mm lens on a patch of a 200 m floor under a sun (64 x 48; closed form
                      albedo E cos / pi)
    mirror_lit_shade  the ground under a canopy lit by a mirror that throws the sun in from outside
                      the focus sphere: the focus does not pay and goes after its first pass (32 x 32;
                      against the mean of two ``--reference-time`` runs A, B of unfocused PPM)

with PPM and AMCMCPPM focused (the default; the chains' uniform samples aimed, each run of their
states weighted by its first sample's weight, core/mcmc.py "Photons from afar") and unfocused, and
``auto`` (``RenderSettings.method``), and
prints relMSE = mean((I - R)^2 / (R^2 + 0.01)) per seed (``error_vs_time.errors``; against the two-run reference
corrected for its noise, (A - B)^2 / 4 per pixel, as ``error_vs_time.py``), the passes, the focus
radius and the chains' passes that aimed:

    python benchmarks/focus_cost.py --time 30 --seeds 2 --jobs 2
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
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from error_vs_time import errors  # noqa: E402

SCENES = {"sky_over_floor": (64, 48), "sunlit_corner": (64, 48), "mirror_lit_shade": (32, 32)}
METHODS = {"ppm": dict(method="ppm"), "ppm-unfocused": dict(method="ppm", focus_photons=False),
           "amcmcppm": dict(method="amcmcppm"),
           "amcmcppm-unfocused": dict(method="amcmcppm", focus_photons=False), "auto": dict(method="auto")}


def closed_form(name, resolution):
    """(h, w, 3) the exact image of ``name``, or None."""
    from core.testing.scenes import SUNLIT_CORNER_SUN
    w, h = resolution
    if name == "sky_over_floor":
        value = 0.5 * 1.0                                   # albedo * sky (the builtin's defaults)
    elif name == "sunlit_corner":
        value = 0.6 * 4.0 * -SUNLIT_CORNER_SUN[2] / np.pi   # albedo E cos / pi
    else:
        return None
    return np.full((h, w, 3), value)


def run_one(name, method, seed, seconds, out):
    from core import RenderSettings, render
    from core.testing.scenes import BUILTIN
    scene = BUILTIN[name](resolution=SCENES[name])
    r = render(scene, RenderSettings(seed=seed, passes=0, time_limit=seconds, workers=1, **METHODS[method]))
    np.savez(out, image=r.image[..., :3], passes=len(r.stats),
             focus=[st["focus_radius"] for st in r.stats], aiming=[st["aiming_workers"] for st in r.stats])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--time", type=float, default=30.0, help="seconds per run")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--reference-time", type=float, default=120.0)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "focus_cost"))
    ap.add_argument("--run-one", nargs=5, metavar=("SCENE", "METHOD", "SEED", "SECONDS", "OUT"),
                    help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.run_one:
        name, method, seed, seconds, out = a.run_one
        return run_one(name, method, int(seed), float(seconds), out)
    os.makedirs(a.out, exist_ok=True)

    def spawn(name, method, seed, seconds):
        out = os.path.join(a.out, f"{name}_{method}_{seed}.npz")
        subprocess.run([sys.executable, os.path.abspath(__file__), "--run-one", name, method, str(seed),
                        str(seconds), out], check=True)
        return dict(np.load(out))

    print("| scene | method | relMSE per seed | passes | focus radius (first, last pass) "
          "| chains' aimed passes |")
    print("|---|---|---|---|---|---|")
    for name in a.scenes:
        with ThreadPoolExecutor(a.jobs) as pool:
            ref = closed_form(name, SCENES[name])
            ref_var = np.zeros_like(ref) if ref is not None else None
            if ref is None:
                refs = [pool.submit(spawn, name, "ppm-unfocused", 1000 + k, a.reference_time)
                        for k in range(2)]
                halves = [f.result()["image"] for f in refs]
                ref, ref_var = 0.5 * (halves[0] + halves[1]), 0.25 * (halves[0] - halves[1]) ** 2
            runs = {(m, s): pool.submit(spawn, name, m, s, a.time)
                    for m in a.methods for s in range(1, a.seeds + 1)}
            results = {key: f.result() for key, f in runs.items()}
        for m in a.methods:
            errs, passes, focus, aimed = [], [], [], []
            for s in range(1, a.seeds + 1):
                r = results[(m, s)]
                errs.append(float(errors(r["image"][None], ref, ref_var)[3][0]))
                passes.append(int(r["passes"]))
                focus.append((float(r["focus"][0]), float(r["focus"][-1])))
                aimed.append(int(np.count_nonzero(r["aiming"])))
            print(f"| {name} | {m} | {', '.join(f'{e:.3g}' for e in errs)} | {', '.join(map(str, passes))} | "
                  f"{', '.join(f'{f0:.3g}, {f1:.3g}' for f0, f1 in focus)} | "
                  f"{', '.join(map(str, aimed)) if m.startswith('amcmcppm') else ''} |", flush=True)


if __name__ == "__main__":
    main()
