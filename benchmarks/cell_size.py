"""What the hash grid's cell size costs: its build, its queries and the whole photon pass.

One eye pass of a built-in scene; for each cell size (in median radii, ``CELL_PER_RADIUS``, the
entry budget lifted so that it is the size asked for) the grid of its measurement points is built,
``--paths`` uniform photons are traced into it, and the grid queries of the first run's photon
pass (recorded once, the same for every grid) are replayed alone. Rounds alternate the order of
the sizes (the machines are shared); medians over rounds:

    python benchmarks/cell_size.py [--scene cornell_box] [--resolution 640 480] [--paths 131072]
                                   [--cells 1 1.5 2 3] [--rounds 3]

Columns: grid entries per point, candidates a photon vertex meets, seconds of the build, of the
replayed queries and of the photon pass, microseconds of the photon pass per vertex, and the
estimated seconds of a pass of ``--pass-paths`` photons (build + photon pass scaled).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import core.hash_grid as hash_grid  # noqa: E402
from core import RenderSettings  # noqa: E402
from core.context import RenderContext  # noqa: E402
from core.eye_pass import trace_eye_pass  # noqa: E402
from core.photon_pass import DepositTarget, path_dims, trace_photons  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402

BATCH = 1 << 14


def photon_pass(ctx, target, settings, n_paths):
    """(seconds, vertices) of tracing ``n_paths`` uniform photons into ``target``."""
    rng = np.random.default_rng(1)
    vertices = 0
    t0 = time.perf_counter()
    for done in range(0, n_paths, BATCH):
        u = rng.random((min(BATCH, n_paths - done), path_dims(settings.max_bounces)))
        vertices += trace_photons(ctx, target, u, settings.max_bounces).vertices
    return time.perf_counter() - t0, vertices


class Recorder:
    """Wraps ``HashGrid.query`` and keeps a copy of every call's arguments."""

    def __init__(self):
        self.calls, self.original = [], hash_grid.HashGrid.query

    def __enter__(self):
        calls, original = self.calls, self.original

        def query(grid, x, normals, directions=None, inner=False):
            calls.append((x.copy(), None if normals is None else normals.copy(),
                          None if directions is None else directions.copy(), inner))
            return original(grid, x, normals, directions, inner)
        hash_grid.HashGrid.query = query
        return self

    def __exit__(self, *exc):
        hash_grid.HashGrid.query = self.original


def candidates(grid, calls):
    """Candidates all the recorded queries meet in ``grid``."""
    total = 0
    for x, *_ in calls:
        keys, _ = grid._cells(x)
        pos = np.minimum(np.searchsorted(grid.cell_keys, keys), len(grid.cell_keys) - 1)
        found = (grid.cell_keys[pos] == keys) & (keys >= 0)
        total += int(np.where(found, grid.cell_start[pos + 1] - grid.cell_start[pos], 0).sum())
    return total


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="cornell_box", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(640, 480))
    ap.add_argument("--paths", type=int, default=131072)
    ap.add_argument("--pass-paths", type=int, default=153600,
                    help="photons of the pass the last column estimates (default: 640x480's automatic count)")
    ap.add_argument("--cells", type=float, nargs="+", default=(1.0, 1.5, 2.0, 3.0))
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    settings = RenderSettings()
    w, h = args.resolution
    ctx = RenderContext(BUILTIN[args.scene](resolution=(w, h)))
    eye = trace_eye_pass(ctx, np.random.default_rng(0), settings.initial_radius_px, settings.max_bounces)
    points = eye.points
    radius = points.base_radius

    def target(grid=None):
        return DepositTarget(points, radius, ctx.table, w * h, ctx.has_shading_normals, grid=grid)
    with Recorder() as recorder:
        photon_pass(ctx, target(), settings, args.paths)
    calls = recorder.calls
    hash_grid.ENTRY_BUDGET, hash_grid.MAX_ENTRIES = 1 << 10, 1 << 30
    rows = {k: [] for k in args.cells}
    for r in range(args.rounds + 1):                  # round 0 warms up
        for k in (args.cells if r % 2 == 0 else args.cells[::-1]):
            hash_grid.CELL_PER_RADIUS = k
            t0 = time.perf_counter()
            grid = hash_grid.HashGrid(points.position, radius, points.ng)
            build = time.perf_counter() - t0
            t0 = time.perf_counter()
            for call in calls:
                grid.query(*call)
            queries = time.perf_counter() - t0
            seconds, vertices = photon_pass(ctx, target(grid), settings, args.paths)
            if r:
                rows[k].append((grid.entry_count / points.count, candidates(grid, calls) / vertices, build,
                                queries, seconds, vertices))
    print(f"{args.scene} {w}x{h}: {points.count} points, {args.paths} paths, {len(calls)} queries; "
          f"medians of {args.rounds} rounds")
    print("| cell (median radii) | entries / point | candidates / vertex | build s | queries s "
          "| photon pass s | us / vertex | pass of --pass-paths s |")
    print("|---|---|---|---|---|---|---|---|")
    for k, runs in rows.items():
        a = np.median(np.array(runs), axis=0)
        per_vertex = a[4] / a[5]
        estimate = a[2] + per_vertex * a[5] * args.pass_paths / args.paths
        print(f"| {k:g} | {a[0]:.2f} | {a[1]:.1f} | {a[2]:.3f} | {a[3]:.3f} | {a[4]:.3f} "
              f"| {1e6 * per_vertex:.2f} | {estimate:.3f} |")


if __name__ == "__main__":
    main()
