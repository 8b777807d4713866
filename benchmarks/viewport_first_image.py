"""How soon the 3D viewport's live render shows its first images (``core.live.LiveRender``).

Each scene and size starts a fresh server process (as the first Rendered-shading redraw does)
and records when the first passes' images can be read, and then, with the server warm, when a
second job (the view moved) shows its first image.  One worker, the scene's default settings.

    python benchmarks/viewport_first_image.py [--scenes cornell_box glass_ceiling_room]
                                              [--sizes 320x180 640x360] [--images 3]
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import RenderSettings  # noqa: E402
from core.live import LiveRender  # noqa: E402
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room"],
                    choices=sorted(BUILTIN))
    ap.add_argument("--sizes", nargs="+", default=["320x180", "640x360"])
    ap.add_argument("--images", type=int, default=3, help="images timed from a fresh server")
    a = ap.parse_args()
    settings = RenderSettings(passes=10_000, workers=1)
    for name in a.scenes:
        for size in a.sizes:
            resolution = tuple(int(v) for v in size.split("x"))
            scene = BUILTIN[name](resolution=resolution)
            live = LiveRender()
            try:
                t0 = time.monotonic()
                live.start(scene, settings)
                fresh = image_times(live, a.images, t0)
                pose = scene.camera.world_from_camera.copy()
                pose[0, 3] += 0.01
                moved = dataclasses.replace(scene.camera, world_from_camera=pose)
                t1 = time.monotonic()
                live.start(dataclasses.replace(scene, camera=moved), settings)
                warm = image_times(live, 1, t1)
            finally:
                live.close()
            print(f"{name} {size}: fresh server, images at {', '.join(f'{t:.2f}' for t in fresh)} s; "
                  f"warm server, a moved view's first image at {warm[0]:.2f} s")


if __name__ == "__main__":
    main()
