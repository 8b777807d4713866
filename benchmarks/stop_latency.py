"""How soon a render answers a stop request (Blender's Esc, the 3D viewport's next job).

Renders a built-in scene with ``core.render`` and a ``should_stop`` that turns True a given time
after the first image, and prints how long after that the render returned; with ``--base REV``
also the core of git revision ``REV`` (extracted beside this checkout's, as
``benchmarks/ab_photon_pass.py`` does), one after the other, each delay in turn.

    python benchmarks/stop_latency.py [--base 7ab4020] [--scene cornell_box] [--resolution 1920 1080]
        [--delays 0.3 0.9 1.5] [--method ppm] [--workers 1]
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from ab_photon_pass import extract  # noqa: E402


def latency(package, scene_name, resolution, delay, method, workers):
    """Seconds from a stop request ``delay`` s after the first image to the render's return."""
    core = importlib.import_module(package)
    scene = importlib.import_module(f"{package}.testing.scenes").BUILTIN[scene_name](resolution=resolution)
    state = {}

    def first_image(result):
        state.setdefault("at", time.perf_counter() + delay)

    def stop():
        return "at" in state and time.perf_counter() >= state["at"]

    settings = core.RenderSettings(method=method, passes=1000, photons_per_pass=100_000, workers=workers)
    result = core.render(scene, settings, on_iteration=first_image, should_stop=stop)
    return time.perf_counter() - state["at"], result.passes


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default=None, help="git revision to compare against")
    ap.add_argument("--scene", default="cornell_box")
    ap.add_argument("--resolution", type=int, nargs=2, default=(1920, 1080))
    ap.add_argument("--delays", type=float, nargs="+", default=[0.3, 0.9, 1.5])
    ap.add_argument("--method", default="ppm", choices=("ppm", "amcmcppm"))
    ap.add_argument("--workers", type=int, default=1)
    a = ap.parse_args()
    packages = ["core"]
    with tempfile.TemporaryDirectory() as tmp:
        if a.base:
            extract(a.base, tmp)
            sys.path.insert(0, tmp)
            packages.insert(0, "core_base")
        for package in packages:
            got = [latency(package, a.scene, tuple(a.resolution), d, a.method, a.workers) for d in a.delays]
            name = f"base ({a.base})" if package == "core_base" else "this checkout"
            print(f"{a.scene} {a.resolution[0]}x{a.resolution[1]} {a.method}, {a.workers} worker(s), {name}: "
                  + ", ".join(f"stop {d} s after the first image answered after {t:.2f} s ({p} passes)"
                              for d, (t, p) in zip(a.delays, got)), flush=True)


if __name__ == "__main__":
    main()
