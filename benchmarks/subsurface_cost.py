"""What subsurface scattering costs: a wax cube on a floor under an area light, rendered with the
wax a Random Walk subsurface material and with it a plain diffuse one, by uniform photons (PPM) and
by the Markov chains, the four variants alternating round by round (one run, one worker).

The eye pass takes one walk per pixel that lands on the wax; every photon that picks the wax's
subsurface part walks too.  A walk is a loop of ray casts over the walks still inside (up to
Cycles' 256 steps), so its cost is the steps of the longest walks in each batch: the chains trace
many small batches (one per iteration), PPM a few big ones.  Printed: seconds per pass (median and
range) and subsurface over diffuse per method, then the cost of a step of the walks' loop (best of
the rounds) for 8 and for 1000 walks into a deep box (albedo 0.9999).

    python benchmarks/subsurface_cost.py [--rounds 3] [--passes 2] [--photons 100000]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import render, subsurface  # noqa: E402
from core.accel import Accel  # noqa: E402
from core.scene import Camera, Lights, Materials  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from core.testing.scenes import MeshBuilder  # noqa: E402


def wax_cube(subsurface, resolution=(96, 96)):
    """A 1 m cube of orange wax (Blender's radii (1, 0.2, 0.1) at Scale 0.5) on a grey floor, lit
    from behind and above by a square area light, or the cube a diffuse of the same colour."""
    wax = {"name": "wax", "diffuse": (0.8, 0.5, 0.3)}
    if subsurface:
        wax.update(subsurface_weight=1.0, subsurface_radius=(0.5, 0.1, 0.05), subsurface_ior=1.4,
                   subsurface_alpha=0.25)
    m = MeshBuilder()
    m.add_quad((-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0), 0)
    m.add_box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0), 1)
    lights = Lights.build([{"kind": "area", "position": (0.0, 2.0, 2.0), "direction": (0.0, -0.8, -0.6),
                            "size": (1.0, 1.0), "power": 300.0}])
    cam = Camera.look_at((0.0, -3.5, 1.5), (0.0, 0.0, 0.5), lens_mm=35.0, resolution=resolution)
    return m.build(Materials.build([{"name": "floor", "diffuse": 0.8}, wax]), lights, cam)


def step_cost(walks, rounds):
    """Seconds per step of ``subsurface.random_walk`` for ``walks`` walks into a box 100 m deep."""
    m = MeshBuilder()
    m.add_box((-100.0, -100.0, -100.0), (100.0, 100.0, 0.0), 0)
    accel = Accel(m.build(Materials.build([{"name": "medium", "diffuse": 0.5}])))
    steps, best = 0, np.inf
    for r in range(rounds):
        rng = np.random.default_rng(r)
        counted = []

        def intersect(rows, origins, dirs, tmax):
            counted.append(len(rows))
            return accel.intersect(origins, dirs, tmax)
        t = time.perf_counter()
        down = np.tile([0.0, 0.0, -1.0], (walks, 1))
        subsurface.random_walk(intersect, 1e-3 * down, down, -down, np.full((walks, 3), 10.0),
                               np.full((walks, 3), 0.9999), np.full(walks, 0.3), np.ones((walks, 3)),
                               lambda rows, step: rng.random((len(rows), subsurface.WALK_NUMBERS)))
        best = min(best, (time.perf_counter() - t) / len(counted))
        steps = len(counted)
    return best, steps


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--passes", type=int, default=2)
    ap.add_argument("--photons", type=int, default=100_000)
    a = ap.parse_args()
    scenes = {False: wax_cube(False), True: wax_cube(True)}
    times = {}
    for r in range(a.rounds):
        for method in ("ppm", "amcmcppm"):
            for sss in (False, True):
                settings = RenderSettings(passes=a.passes, photons_per_pass=a.photons, workers=1, seed=r,
                                          method=method)
                t = time.perf_counter()
                render(scenes[sss], settings)
                times.setdefault((method, sss), []).append((time.perf_counter() - t) / a.passes)
    for method in ("ppm", "amcmcppm"):
        for sss in (False, True):
            t = np.array(times[method, sss])
            print(f"{method:9s} {'subsurface' if sss else 'diffuse':10s} s/pass median {np.median(t):.3f} "
                  f"range {t.min():.3f}-{t.max():.3f}")
        ratio = np.array(times[method, True]) / np.array(times[method, False])
        print(f"{method:9s} subsurface / diffuse: median {np.median(ratio):.2f} "
              f"range {ratio.min():.2f}-{ratio.max():.2f}")
    for walks in (8, 1000):
        seconds, steps = step_cost(walks, a.rounds)
        print(f"walk loop, {walks:4d} walks: {seconds * 1e6:.0f} microseconds a step ({steps} steps)")


if __name__ == "__main__":
    main()
