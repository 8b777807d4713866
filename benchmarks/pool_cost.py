"""What do worker processes cost on a small render?  One worker against two, the same photons.

``workers=2`` starts two processes that each build the scene and (AMCMCPPM) their own chains and
trace half of every pass; ``workers=1`` traces the whole pass in this process.  For each scene,
size and method this script renders both ways with the same photons per pass in all (``--photons``
for one worker, half each for two) and prints, per round, the wall time and the CPU time of this
process and its children, and the ratios two / one.  The two ways alternate within every round,
so each ratio is taken under the same machine load; medians and ranges over rounds are printed.
A CPU ratio near 1 means the pool costs nothing extra; a wall ratio near 0.5 means two workers
are twice as fast.  (Stop 47: the parity tests at 64 x 64 spent 1.7 times the CPU with two.)

    python benchmarks/pool_cost.py [--scenes cornell_box glass_ceiling_room] [--sizes 64x64 320x240]
                                   [--methods ppm amcmcppm] [--passes 8] [--photons 100000] [--rounds 2]
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from core import RenderSettings, render  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402


def cpu_seconds():
    """(this process, its finished children) user + system seconds."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime


def timed_render(scene, settings):
    """(wall seconds, CPU seconds of this process and the workers) of one render."""
    c0, t0 = cpu_seconds(), time.perf_counter()
    result = render(scene, settings)
    wall, c1 = time.perf_counter() - t0, cpu_seconds()
    assert np.isfinite(result.image).all()
    return wall, (c1[0] - c0[0]) + (c1[1] - c0[1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room"])
    ap.add_argument("--sizes", nargs="+", default=["64x64", "320x240"])
    ap.add_argument("--methods", nargs="+", default=["ppm", "amcmcppm"])
    ap.add_argument("--passes", type=int, default=8)
    ap.add_argument("--photons", type=int, default=100_000, help="photons per pass in all")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)
    print(f"{args.passes} passes of {args.photons} photons in all; ratios two workers / one "
          f"(median, range over {args.rounds} rounds)")
    print(f"{'scene':20s} {'size':8s} {'method':9s} {'wall 1':>7s} {'cpu 1':>7s} {'wall 2':>7s} "
          f"{'cpu 2':>7s}   wall ratio            cpu ratio")
    for name in args.scenes:
        for size in args.sizes:
            w, h = (int(v) for v in size.split("x"))
            scene = BUILTIN[name](resolution=(w, h))
            for method in args.methods:
                base = RenderSettings(method=method, passes=args.passes, seed=1)
                runs = {1: [], 2: []}
                for _ in range(args.rounds):
                    for workers in (1, 2):
                        s = base.replace(workers=workers, photons_per_pass=args.photons // workers)
                        runs[workers].append(timed_render(scene, s))
                one, two = np.array(runs[1]), np.array(runs[2])
                wall, cpu = two[:, 0] / one[:, 0], two[:, 1] / one[:, 1]
                print(f"{name:20s} {size:8s} {method:9s} {np.median(one[:, 0]):7.2f} "
                      f"{np.median(one[:, 1]):7.2f} {np.median(two[:, 0]):7.2f} {np.median(two[:, 1]):7.2f}"
                      f"   {np.median(wall):.2f} ({wall.min():.2f}-{wall.max():.2f})"
                      f"      {np.median(cpu):.2f} ({cpu.min():.2f}-{cpu.max():.2f})", flush=True)


if __name__ == "__main__":
    main()
