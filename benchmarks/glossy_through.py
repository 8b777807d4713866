"""Where camera paths should end on glossy surfaces: error for the same time with camera paths that
end on a glossy lobe (a measurement point gathers photons there) against paths that go on through it
(``RenderSettings.glossy_through_roughness``), for a range of roughness.

The scene is the Cornell box (``core.testing.scenes.cornell_box``) with a polished floor (a diffuse
of 0.4 under a Fresnel layer of IOR 1.5, Principled-like) and a metal tall box (glossy 0.8), both of
roughness r.  For each r and mode, ``--seeds`` renders of ``--time`` seconds (one worker each,
``--jobs`` at a time, AMCMCPPM with the default settings) are compared with a reference: the mean
of one long render in each mode (both are consistent), corrected for the reference's own noise as
``error_vs_time.py`` does: relMSE = mean(((I - R)^2 - (A - B)^2 / 4) / (R^2 + 0.01)).

    python benchmarks/glossy_through.py --roughness 0.05 0.1 0.2 0.35 --time 20 --reference-time 120

prints a table of relMSE ratios through / end (below 1: going on through the lobe is better) and
writes it to ``benchmarks/results/glossy_through.md``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from error_vs_time import errors  # noqa: E402

from core import RenderSettings, render  # noqa: E402
from core.scene import Camera, Materials  # noqa: E402
from core.testing.scenes import cornell_box  # noqa: E402

MODES = {"end": 0.0, "through": 1.0}


def glossy_cornell(roughness, resolution, glossy="both", view="level"):
    """The Cornell box with a polished floor and a metal tall box of ``roughness`` (``glossy``:
    "both", or only the "floor" or the "metal" box glossy, the other diffuse), seen by the box's
    camera (``view`` "level": the lamp's reflection in the floor is out of the picture) or from
    higher up, looking down ("down": the floor shows the lamp's highlight)."""
    box = cornell_box(resolution)
    if view == "down":
        box = box.replace(camera=Camera.look_at((0, -3.9, 1.6), (0, 0, -0.3), lens_mm=35.0, sensor_width=36.0,
                                                resolution=resolution))
    f0 = 0.04
    specs = [{"name": n, **s} for n, s in (
        ("white", {"diffuse": 0.73}), ("red", {"diffuse": (0.65, 0.05, 0.05)}),
        ("green", {"diffuse": (0.12, 0.45, 0.15)}), ("lamp", {"emission": (17.0, 12.0, 4.0)}),
        ("floor", {"diffuse": 0.4, "glossy": f0, "roughness": roughness, "glossy_fresnel_ior": 1.5,
                   "glossy_fresnel_rise": 1.0 - f0, "glossy_multiscatter": 0.1, "diffuse_layer": f0}),
        ("metal", {"glossy": 0.8, "roughness": roughness}))]
    ids = np.array(box.material_ids)
    if glossy in ("both", "floor"):
        ids[:2] = 4                       # the floor quad (added first)
    if glossy in ("both", "metal"):
        ids[22:34] = 5                    # the tall box (the second box)
    return box.replace(materials=Materials.build(specs), material_ids=ids).validate()


def run(job):
    """Image of one render: job = (roughness, resolution, glossy, view, mode, seconds, seed)."""
    roughness, resolution, glossy, view, mode, seconds, seed = job
    settings = RenderSettings(time_limit=seconds, passes=0, workers=1, seed=seed,
                              glossy_through_roughness=MODES[mode])
    image = render(glossy_cornell(roughness, resolution, glossy, view), settings).image
    return image[..., :3].astype(np.float64)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--roughness", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.35])
    p.add_argument("--time", type=float, default=20.0, help="seconds per measured render")
    p.add_argument("--reference-time", type=float, default=120.0, help="seconds per reference render")
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--resolution", type=int, nargs=2, default=(64, 48))
    p.add_argument("--glossy", choices=("both", "floor", "metal"), default="both",
                   help="which surfaces are glossy: the polished floor, the metal box or both")
    p.add_argument("--view", choices=("level", "down"), default="level",
                   help="the box's camera, or one looking down on the floor's highlight of the lamp")
    p.add_argument("--output", default=os.path.join(ROOT, "benchmarks", "results", "glossy_through.md"))
    a = p.parse_args(argv)
    rows = []
    res = tuple(a.resolution)
    with ProcessPoolExecutor(a.jobs) as pool:
        for r in a.roughness:
            refs = list(pool.map(run, [(r, res, a.glossy, a.view, m, a.reference_time, 1000) for m in MODES]))
            ref = 0.5 * (refs[0] + refs[1])
            half_diff2 = 0.25 * (refs[0] - refs[1]) ** 2
            jobs = [(r, res, a.glossy, a.view, m, a.time, s) for s in range(a.seeds) for m in MODES]
            images = list(pool.map(run, jobs))
            corrected = errors(np.stack(images), ref, half_diff2)[3]      # relMSE less the reference's noise
            err = {m: [float(e) for job, e in zip(jobs, corrected) if job[4] == m] for m in MODES}
            means = {m: float(np.mean(v)) for m, v in err.items()}
            rows.append((r, means["end"], means["through"], means["through"] / means["end"],
                         float(np.mean(half_diff2 / (ref * ref + 0.01)))))
            print(f"roughness {r}: relMSE end {means['end']:.4g} (seeds {np.round(err['end'], 4)}), "
                  f"through {means['through']:.4g} (seeds {np.round(err['through'], 4)}), "
                  f"ratio {rows[-1][3]:.3f}", flush=True)
    lines = [f"# Camera paths through glossy lobes ({a.glossy} glossy, {a.view} view; "
             f"{time.strftime('%Y-%m-%d')}, {a.seeds} seeds x {a.time:g} s, "
             f"references 2 x {a.reference_time:g} s, {a.resolution[0]}x{a.resolution[1]})", "",
             "| roughness | relMSE, paths end there | relMSE, paths go on through | ratio through / end | "
             "reference noise (relMSE) |", "|---|---|---|---|---|"]
    lines += [f"| {r:g} | {e:.4g} | {t:.4g} | {q:.3f} | {n:.2g} |" for r, e, t, q, n in rows]
    out = a.output
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
