"""How soon the 3D viewport's live render shows its first images (``core.live.LiveRender``).

Each scene and size starts a fresh server process (as the first Rendered-shading redraw does)
and records when the first passes' images can be read, and then, with the server warm, when a
second job (the view moved: the server keeps its scene) shows its first image, a third (a
material edited: the scene sent again, its BVH kept), a fourth (a vertex moved: the scene sent
again, where the scene is big enough with the earlier BVH kept and the moved triangles' and those
around their old place built apart: ``core.accel.SplitScene``) and a fifth (the vertex moved again);
with ``--lift-material M`` also a sixth and a seventh (the triangles of material M, an object,
lifted by a thousandth of the scene's extent, twice).  ``--subdivide K`` splits every triangle into
4**K (``core.testing.scenes.subdivide``) for a scene whose BVH costs.  One worker, the
scene's default settings but the first pass's photons: each of ``--first-pass-photons`` in turn
(0: the automatic count's own ramp, from ``AUTO_PHOTONS_MIN``; the viewport's
``VIEWPORT_FIRST_PHOTONS``), alternating over ``--rounds``, and the ratio of each one's times to
the first one's (medians).

    python benchmarks/viewport_first_image.py [--scenes cornell_box glass_ceiling_room]
        [--sizes 320x180 640x360] [--images 3] [--first-pass-photons 0 10000] [--rounds 3]
        [--subdivide K] [--lift-material M] [--no-huge-pages]

``--no-huge-pages`` runs the server without NumPy's advice for huge pages (``NUMPY_MADVISE_HUGEPAGE=0``
in the environment the server inherits).  An image of over ``core.live.PREVIEW_PIXELS`` pixels
first gets a coarse preview: the times above are of the job's passes, the previews' are printed
apart.
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
from core.testing.scenes import BUILTIN, subdivide  # noqa: E402


def image_times(live, count, t0, timeout=600.0):
    """Seconds after ``t0`` at which the current job's first ``count`` images (of its passes) could
    be read, and at which its preview could (``core.live.PREVIEW_PIXELS``; None: none seen)."""
    times, preview = [], None
    while len(times) < count:
        got = live.latest()
        if got is not None and got[1].get("preview"):
            preview = time.monotonic() - t0
        elif got is not None:
            times.append(time.monotonic() - t0)
        if time.monotonic() - t0 > timeout:
            raise RuntimeError(f"no {count} images within {timeout} s")
        time.sleep(0.005)
    return times, preview


def edits(scene, lift=None):
    """The scene with its view moved, then a material edited, then a vertex moved, twice, then
    (``lift``: a material id) that material's triangles lifted, twice."""
    pose = scene.camera.world_from_camera.copy()
    pose[0, 3] += 0.01
    moved = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, world_from_camera=pose))
    colours = scene.materials.diffuse_color.copy()
    colours[0] *= 0.9
    materials = dataclasses.replace(moved.materials, diffuse_color=colours)
    recoloured = dataclasses.replace(moved, materials=materials)
    vertices = scene.vertices.copy()
    vertices[0] += 1e-4
    again = vertices.copy()
    again[0] += 1e-4
    out = [moved, recoloured, dataclasses.replace(recoloured, vertices=vertices),
           dataclasses.replace(recoloured, vertices=again)]
    if lift is not None:
        corners = np.unique(scene.triangles[scene.material_ids == lift])
        step = 1e-3 * float(np.max(np.subtract(*scene.bounds()[::-1])))
        lifted = again
        for _ in range(2):
            lifted = lifted.copy()
            lifted[corners, 2] += step
            out.append(dataclasses.replace(recoloured, vertices=lifted))
    return out


def job_times(scene, settings, images, lift=None):
    """Times of the first ``images`` images from a fresh server, then of the first image of each of
    ``edits``; and the times of their previews (NaN: none)."""
    live = LiveRender()
    previews = []
    try:
        t0 = time.monotonic()
        live.start(scene, settings)
        times, preview = image_times(live, images, t0)
        previews.append(preview)
        for edited in edits(scene, lift):
            t1 = time.monotonic()
            live.start(edited, settings)
            got, preview = image_times(live, 1, t1)
            times += got
            previews.append(preview)
    finally:
        live.close()
    return times, [np.nan if p is None else p for p in previews]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room"],
                    choices=sorted(BUILTIN))
    ap.add_argument("--sizes", nargs="+", default=["320x180", "640x360"])
    ap.add_argument("--images", type=int, default=3, help="images timed from a fresh server")
    ap.add_argument("--first-pass-photons", nargs="+", type=int, default=[0, VIEWPORT_FIRST_PHOTONS])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--subdivide", type=int, default=0, help="split every triangle into 4**K")
    ap.add_argument("--lift-material", type=int, default=None,
                    help="also time an object lifted, twice: this material's triangles")
    ap.add_argument("--no-huge-pages", action="store_true",
                    help="the server's NumPy does not advise huge pages (NUMPY_MADVISE_HUGEPAGE=0)")
    a = ap.parse_args()
    if a.no_huge_pages:
        os.environ["NUMPY_MADVISE_HUGEPAGE"] = "0"      # (read by the server's NumPy at its import)
    counts = a.first_pass_photons
    for name in a.scenes:
        for size in a.sizes:
            resolution = tuple(int(v) for v in size.split("x"))
            scene = subdivide(BUILTIN[name](resolution=resolution), a.subdivide)
            times = {n: [] for n in counts}
            previews = {n: [] for n in counts}
            for _ in range(a.rounds):
                for n in counts:
                    settings = RenderSettings(passes=10_000, workers=1, first_pass_photons=n)
                    got, preview = job_times(scene, settings, a.images, a.lift_material)
                    times[n].append(got)
                    previews[n].append(preview)
            base = np.median(times[counts[0]], axis=0)
            edited = 4 if a.lift_material is None else 6
            for n in counts:
                t = np.median(times[n], axis=0)
                lifted = "" if a.lift_material is None else (
                    f", of an object lifted {t[-2]:.2f} s, lifted again {t[-1]:.2f} s")
                e = t[-edited:]
                print(f"{name} ({scene.triangle_count:,} triangles) {size}, first pass {n or 'automatic'}: "
                      f"fresh server, images at {', '.join(f'{v:.2f}' for v in t[:-edited])} s; first image "
                      f"of a moved view at {e[0]:.2f} s, of an edited material {e[1]:.2f} s, of a moved "
                      f"vertex {e[2]:.2f} s, moved again {e[3]:.2f} s{lifted} (median of {a.rounds}; "
                      f"/ first count: "
                      f"{', '.join(f'{v:.2f}' for v in t / base)})", flush=True)
                p = np.median(previews[n], axis=0)
                if np.isfinite(p).any():
                    print(f"  previews (PREVIEW_PIXELS) at {', '.join(f'{v:.2f}' for v in p)} s: the fresh "
                          "server's, then each edit's in the order above", flush=True)


if __name__ == "__main__":
    main()
