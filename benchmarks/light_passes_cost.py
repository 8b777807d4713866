"""Cost of Cycles' light passes (``RenderSettings.data_passes`` = ``core.light_passes.LIGHT_PASSES``:
the eye pass's emission and colours by first event, the photons' extra slot blocks and per-pass
pixel sums, ``core/light_passes.py``) and of light groups (every emitter in a group of its own
kind, ``core.testing.scenes.with_light_groups``: one pass per analytic light, one for the emissive
meshes and one for the world; copies of the pairs on a block per group, and with the bias
correction on an inner block per group).

Per scene, whole renders in one process (``workers=1``) alternating without and with the passes in
every round, so each round's ratio shares the machine's load (median and range over rounds), for
uniform photons and the Markov chains; then the peak of memory Python allocates (``tracemalloc``)
in one render each way.

    python benchmarks/light_passes_cost.py [--scenes cornell_box glass_ceiling_room hole_mirror_glass]
                                           [--resolution 320 240] [--rounds 3] [--passes 3]
                                           [--variants light_passes light_groups]
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
from core.light_passes import LIGHT_PASSES, LIGHTGROUP_PREFIX  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from core.testing.scenes import BUILTIN, with_light_groups  # noqa: E402


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


def compare(label, run, both, rounds):
    """Print ``label`` and the cost of ``both[1]`` against ``both[0]``: ``run(x, seed)`` makes a render
    of each (the two alternate within every round): the medians of their times, the median and
    range of the ratio over the rounds, and the peak traced memory of one render each way."""
    pairs = np.array([[timed(run(x, r)) for x in both] for r in range(rounds)])
    ratio = pairs[:, 1] / pairs[:, 0]
    memory = [peak_mib(run(x, 0)) for x in both]
    print(f"{label}: without {np.median(pairs[:, 0]):.2f} s, with {np.median(pairs[:, 1]):.2f} s, ratio "
          f"{np.median(ratio):.3f} ({ratio.min():.3f}-{ratio.max():.3f}); peak traced memory "
          f"{memory[0]:.0f} -> {memory[1]:.0f} MiB ({memory[1] / memory[0]:.2f}x)", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room", "hole_mirror_glass"])
    parser.add_argument("--resolution", nargs=2, type=int, default=[320, 240])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--passes", type=int, default=3)
    parser.add_argument("--variants", nargs="+", default=["light_passes", "light_groups"],
                        choices=["light_passes", "light_groups"])
    args = parser.parse_args()
    size = f"{args.resolution[0]}x{args.resolution[1]}"
    for name in args.scenes:
        # (the same scene for both: its groups cost nothing unless their passes are asked for)
        scene = with_light_groups(BUILTIN[name](resolution=tuple(args.resolution)))
        variants = {"light_passes": LIGHT_PASSES,
                    "light_groups": tuple(LIGHTGROUP_PREFIX + g for g in scene.light_groups)}
        for method in ("ppm", "amcmcppm"):
            def run(passes, seed=0):
                settings = RenderSettings(passes=args.passes, workers=1, seed=seed, method=method,
                                          data_passes=passes)
                return lambda: render(scene, settings)
            for variant in args.variants:
                compare(f"{name} {size} {method}, {args.passes} passes, {variant} ({len(variants[variant])})",
                        run, ((), variants[variant]), args.rounds)


if __name__ == "__main__":
    main()
