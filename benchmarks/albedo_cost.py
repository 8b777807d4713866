"""Cost of the Denoising Albedo pass (``RenderSettings.data_passes=("albedo",)``, Cycles' rule along
the camera paths: ``core.eye_pass.AlbedoPaths``).

Two timings per scene, each alternating with and without the pass in every round, so each
round's ratio shares the machine's load (median and range over rounds):

* the eye pass alone (``trace_eye_pass``, same random numbers both ways);
* whole renders of a few passes in one process (``core.render``, ``workers=1``), whose photon pass
  the albedo does not touch: the share of a pass the albedo costs.

    python benchmarks/albedo_cost.py [--scenes cornell_box glass_ceiling_room] [--resolution 640 480]
                                     [--rounds 5] [--passes 4]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import render  # noqa: E402
from core.context import RenderContext  # noqa: E402
from core.eye_pass import trace_eye_pass  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402


def timed(fn):
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room"])
    parser.add_argument("--resolution", nargs=2, type=int, default=[640, 480])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--passes", type=int, default=4)
    args = parser.parse_args()
    for name in args.scenes:
        scene = BUILTIN[name](resolution=tuple(args.resolution))
        ctx = RenderContext(scene)
        eye, whole = [], []
        for r in range(args.rounds):
            times = {}
            for passes in ((), ("albedo",)):
                times[passes] = timed(lambda: trace_eye_pass(ctx, np.random.default_rng([r]), 4.0, 8, passes))
            eye.append((times[()], times[("albedo",)]))
            for passes in ((), ("albedo",)):
                settings = RenderSettings(passes=args.passes, workers=1, seed=r, data_passes=passes)
                times[passes] = timed(lambda: render(scene, settings))
            whole.append((times[()], times[("albedo",)]))
        for label, pairs in (("eye pass", eye), (f"render of {args.passes} passes", whole)):
            pairs = np.array(pairs)
            ratio = pairs[:, 1] / pairs[:, 0]
            print(f"{name} {args.resolution[0]}x{args.resolution[1]}, {label}: without "
                  f"{np.median(pairs[:, 0]):.3f} s, with the albedo {np.median(pairs[:, 1]):.3f} s, ratio "
                  f"{np.median(ratio):.3f} ({ratio.min():.3f}-{ratio.max():.3f})")


if __name__ == "__main__":
    main()
