"""When does the first image appear, and does a time limit hold?  This checkout against a base revision.

An artist who presses F12 waits for the first pass before Blender shows anything, and a render
with a time limit ends with the pass that crosses it.  For each version of ``core`` (this
checkout and ``--base``, extracted with ``git archive``) this script renders one scene with
default settings and a time limit, each render in a fresh process (worker start-up included),
and prints the times at which passes 1, 2 and 3 reached ``on_iteration``, the time ``render()``
returned, and the photon paths traced.  Versions alternate within every round, so each round's
ratio is taken under the same machine load; medians and ranges over rounds are printed.

    python benchmarks/first_image.py [--base HEAD~1] [--scene cornell_box] [--resolution 1920 1080]
                                     [--method ppm] [--time-limit 40] [--rounds 3] [--workers 0]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from ab_photon_pass import extract  # noqa: E402

_RUN = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
from core import RenderSettings, render
from core.testing.scenes import BUILTIN
scene_name, w, h, method, limit, workers = sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5], \
    float(sys.argv[6]), int(sys.argv[7])
scene = BUILTIN[scene_name](resolution=(w, h))
times = []
t0 = time.perf_counter()
result = render(scene, RenderSettings(method=method, passes=0, time_limit=limit, workers=workers),
                on_iteration=lambda r: times.append(time.perf_counter() - t0))
total = time.perf_counter() - t0
print(json.dumps({"pass_times": times, "total": total, "passes": result.passes,
                  "paths": sum(s["paths_traced"] for s in result.stats)}))
"""


def run(path, a):
    out = subprocess.run([sys.executable, "-c", _RUN, path, a.scene, *map(str, a.resolution), a.method,
                          str(a.time_limit), str(a.workers)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="HEAD~1")
    ap.add_argument("--scene", default="cornell_box")
    ap.add_argument("--resolution", type=int, nargs=2, default=(1920, 1080))
    ap.add_argument("--method", default="ppm", choices=("ppm", "amcmcppm"))
    ap.add_argument("--time-limit", type=float, default=40.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--workers", type=int, default=0)
    a = ap.parse_args()
    base_dir = tempfile.mkdtemp(prefix="first_image_")
    extract(a.base, base_dir, package="core")
    print(f"{a.scene} {a.resolution[0]}x{a.resolution[1]} {a.method}, time limit {a.time_limit:g} s, "
          f"workers {a.workers or 'auto'}; base {a.base}")
    rows = {"base": [], "this": []}
    for r in range(a.rounds):
        for name, path in (("base", base_dir), ("this", ROOT)):
            res = run(path, a)
            rows[name].append(res)
            first = ", ".join(f"{t:.1f}" for t in res["pass_times"][:3])
            print(f"round {r + 1} {name}: passes 1-3 shown at {first} s; returned at {res['total']:.1f} s "
                  f"after {res['passes']} passes, {res['paths']:,} paths")

    def summary(label, values):
        v = np.array(values)
        return f"{label} {np.median(v):.2f} (range {v.min():.2f}-{v.max():.2f})"

    pairs = list(zip(rows["base"], rows["this"]))
    print(summary("first image, this / base:", [t["pass_times"][0] / b["pass_times"][0] for b, t in pairs]))
    print(summary("overshoot of the time limit (s), base:", [b["total"] - a.time_limit for b, _ in pairs]))
    print(summary("overshoot of the time limit (s), this:", [t["total"] - a.time_limit for _, t in pairs]))
    print(summary("paths traced per second, this / base:",
                  [(t["paths"] / t["total"]) / (b["paths"] / b["total"]) for b, t in pairs]))


if __name__ == "__main__":
    main()
