"""What the chains' visible cells cost (``core/visible_cells.py``): adding a pass's points and
testing photon vertices, against the pass's other work, at a large image size.

For a scene at 1920x1080 this traces a few eye passes and prints, per pass, the time to trace
the eye pass, to build its hash grid (``HashGrid`` inside ``DepositTarget``) and to add its
points to the cells (``VisibleCells.extended``, which the integrator does in the first four
passes and every eighth), the cells' key count, and the time per vertex of
``VisibleCells.contains`` on the measurement points themselves.  It also prints how many of
a pass's points the lone-point rule (``MIN_POINTS``) leaves out.

    python benchmarks/visible_cells_cost.py [--scene glass_ceiling_room] [--resolution 1920 1080]
                                            [--passes 4]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core.context import RenderContext  # noqa: E402
from core.eye_pass import trace_eye_pass  # noqa: E402
from core.photon_pass import DepositTarget  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402
from core.visible_cells import VisibleCells  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="glass_ceiling_room", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(1920, 1080))
    ap.add_argument("--passes", type=int, default=4)
    args = ap.parse_args()
    scene = BUILTIN[args.scene](resolution=tuple(args.resolution))
    ctx = RenderContext(scene)
    settings = RenderSettings()
    n_pixels = args.resolution[0] * args.resolution[1]
    cells = VisibleCells()
    print(f"{args.scene} {args.resolution[0]}x{args.resolution[1]}")
    print("pass  points  eye pass  grid  cells.extended  (all points)  keys  left out  contains per point")
    for i in range(args.passes):
        t0 = time.perf_counter()
        eye = trace_eye_pass(ctx, np.random.default_rng([0, i]), settings.initial_radius_px,
                             settings.max_bounces)
        pts = eye.points
        t1 = time.perf_counter()
        DepositTarget(pts, pts.base_radius, ctx.table, n_pixels, ctx.has_shading_normals)
        t2 = time.perf_counter()
        new = cells.extended(pts.position, pts.ng, pts.base_radius)
        t3 = time.perf_counter()
        cells.extended(pts.position, pts.ng, pts.base_radius, min_points=1)
        t4 = time.perf_counter()
        cells = new
        inside = cells.contains(pts.position, pts.ng)
        t5 = time.perf_counter()
        n = len(pts.position)
        print(f"{i:4d}  {n:6d}  {t1 - t0:7.2f} s  {t2 - t1:5.2f} s  {t3 - t2:8.2f} s  {t4 - t3:12.2f} s  "
              f"{cells.key_count:9d}  {1 - inside.mean():7.4f}  {(t5 - t4) / max(n, 1) * 1e6:8.2f} us")


if __name__ == "__main__":
    main()
