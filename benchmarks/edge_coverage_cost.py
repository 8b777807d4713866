"""What the edge coverage costs: the same render with ``RenderSettings.edge_coverage`` on and off.

A built-in scene is rendered with PPM for ``--passes`` passes in this process (one worker, the
same seed), the two settings alternating for ``--rounds`` rounds.  Printed: the wall time of
each, the main process's time to prepare the next pass (``prepare_next_s``: the eye pass, its
grid and, with the coverage, the probes) summed over the passes, and the ratio of the medians
(with over without; one run, so the ratio, not the times, is the figure to quote).

    python benchmarks/edge_coverage_cost.py [--scene hole_mirror_glass] [--resolution 64 48]
        [--passes 150] [--rounds 2]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import RenderSettings, render  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="hole_mirror_glass", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(64, 48))
    ap.add_argument("--passes", type=int, default=150)
    ap.add_argument("--rounds", type=int, default=2)
    a = ap.parse_args()
    scene = BUILTIN[a.scene](resolution=tuple(a.resolution))
    wall = {True: [], False: []}
    for _ in range(a.rounds):
        for on in (True, False):
            settings = RenderSettings(method="ppm", passes=a.passes, workers=1, seed=1, edge_coverage=on)
            t0 = time.perf_counter()
            result = render(scene, settings)
            wall[on].append(time.perf_counter() - t0)
            prepare = sum(s.get("prepare_next_s", 0.0) for s in result.stats)
            print(f"edge coverage {'on ' if on else 'off'}: {wall[on][-1]:.2f} s, preparing passes "
                  f"{prepare:.2f} s", flush=True)
    ratios = np.array(wall[True]) / np.array(wall[False])
    print(f"{a.scene} {a.resolution[0]}x{a.resolution[1]}, {a.passes} PPM passes: with the coverage "
          f"{np.median(wall[True]) / np.median(wall[False]):.3f} of the time without "
          f"(rounds {ratios.min():.3f}-{ratios.max():.3f})")


if __name__ == "__main__":
    main()
