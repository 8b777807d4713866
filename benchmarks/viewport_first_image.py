"""How soon the 3D viewport's live render shows its first images (``core.live.LiveRender``).

Each scene and size starts a fresh server process (as the first Rendered-shading redraw does)
and records when the first passes' images can be read, and then, with the server warm, when a
second job (the view moved) shows its first image.  One worker, the scene's default settings
but the first pass's photons: each of ``--first-pass-photons`` in turn (0: the automatic count's
own ramp, from ``AUTO_PHOTONS_MIN``; the viewport's ``VIEWPORT_FIRST_PHOTONS``), alternating over
``--rounds``, and the ratio of each one's times to the first one's (medians).

    python benchmarks/viewport_first_image.py [--scenes cornell_box glass_ceiling_room]
        [--sizes 320x180 640x360] [--images 3] [--first-pass-photons 0 10000] [--rounds 3]
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

from core import RenderSettings  # noqa: E402
from core.live import LiveRender  # noqa: E402
from core.settings import VIEWPORT_FIRST_PHOTONS  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402


def image_times(live, count, t0, timeout=600.0):
    """Seconds after ``t0`` at which the current job's first ``count`` images could be read."""
    times = []
    while len(times) < count:
        if live.latest() is not None:
            times.append(time.monotonic() - t0)
        if time.monotonic() - t0 > timeout:
            raise RuntimeError(f"no {count} images within {timeout} s")
        time.sleep(0.005)
    return times


def job_times(scene, settings, images):
    """(times of the first ``images`` images from a fresh server, time of a moved view's first image)."""
    live = LiveRender()
    try:
        t0 = time.monotonic()
        live.start(scene, settings)
        fresh = image_times(live, images, t0)
        pose = scene.camera.world_from_camera.copy()
        pose[0, 3] += 0.01
        moved = dataclasses.replace(scene.camera, world_from_camera=pose)
        t1 = time.monotonic()
        live.start(dataclasses.replace(scene, camera=moved), settings)
        warm = image_times(live, 1, t1)
    finally:
        live.close()
    return fresh + warm


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room"],
                    choices=sorted(BUILTIN))
    ap.add_argument("--sizes", nargs="+", default=["320x180", "640x360"])
    ap.add_argument("--images", type=int, default=3, help="images timed from a fresh server")
    ap.add_argument("--first-pass-photons", nargs="+", type=int, default=[0, VIEWPORT_FIRST_PHOTONS])
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    counts = a.first_pass_photons
    for name in a.scenes:
        for size in a.sizes:
            resolution = tuple(int(v) for v in size.split("x"))
            scene = BUILTIN[name](resolution=resolution)
            times = {n: [] for n in counts}
            for _ in range(a.rounds):
                for n in counts:
                    settings = RenderSettings(passes=10_000, workers=1, first_pass_photons=n)
                    times[n].append(job_times(scene, settings, a.images))
            base = np.median(times[counts[0]], axis=0)
            for n in counts:
                t = np.median(times[n], axis=0)
                print(f"{name} {size}, first pass {n or 'automatic'}: fresh server, images at "
                      f"{', '.join(f'{v:.2f}' for v in t[:-1])} s; warm server, a moved view's first "
                      f"image at {t[-1]:.2f} s (median of {a.rounds}; / first count: "
                      f"{', '.join(f'{v:.2f}' for v in t / base)})", flush=True)


if __name__ == "__main__":
    main()
