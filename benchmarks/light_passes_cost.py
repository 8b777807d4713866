"""Cost of Cycles' light passes (``RenderSettings.data_passes`` = ``core.light_passes.LIGHT_PASSES``:
the eye pass's emission and colours by first event, the photons' extra slot blocks and per-pass
pixel sums, ``core/light_passes.py``).

Per scene, whole renders in one process (``workers=1``) alternating without and with all the light
passes in every round, so each round's ratio shares the machine's load (median and range over
rounds), for uniform photons and the Markov chains; then the peak of memory Python allocates
(``tracemalloc``) in one render each way.

    python benchmarks/light_passes_cost.py [--scenes cornell_box glass_ceiling_room hole_mirror_glass]
                                           [--resolution 320 240] [--rounds 3] [--passes 3]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import render  # noqa: E402
from core.light_passes import LIGHT_PASSES  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402

VARIANTS = ((), LIGHT_PASSES)


def timed(fn):
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def peak_mib(fn):
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2 ** 20


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room", "hole_mirror_glass"])
    parser.add_argument("--resolution", nargs=2, type=int, default=[320, 240])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--passes", type=int, default=3)
    args = parser.parse_args()
    size = f"{args.resolution[0]}x{args.resolution[1]}"
    for name in args.scenes:
        scene = BUILTIN[name](tuple(args.resolution))
        for method in ("ppm", "amcmcppm"):
            def run(passes, seed=0):
                settings = RenderSettings(passes=args.passes, workers=1, seed=seed, method=method,
                                          data_passes=passes)
                return lambda: render(scene, settings)
            pairs = np.array([[timed(run(passes, r)) for passes in VARIANTS] for r in range(args.rounds)])
            ratio = pairs[:, 1] / pairs[:, 0]
            memory = [peak_mib(run(passes)) for passes in VARIANTS]
            print(f"{name} {size} {method}, {args.passes} passes: without {np.median(pairs[:, 0]):.2f} s, "
                  f"with the light passes {np.median(pairs[:, 1]):.2f} s, ratio {np.median(ratio):.3f} "
                  f"({ratio.min():.3f}-{ratio.max():.3f}); peak traced memory {memory[0]:.0f} -> "
                  f"{memory[1]:.0f} MiB ({memory[1] / memory[0]:.2f}x)")


if __name__ == "__main__":
    main()
