"""What a compiled deposit gather would save: NumPy ``HashGrid.query`` against a Numba kernel.

The photon pass spends most of its time finding the measurement points near each photon
vertex (``benchmarks/throughput.py``).  This replays the grid queries of one batch of
photons on a sample scene's first pass through the project's NumPy query and through a
straightforward Numba kernel with the same test, checks that both find the same pairs,
and reports the time of each per vertex and per candidate.  Numba is *not* a project
dependency (it would also have to ship inside the extension); install it to run this:

    pip install numba
    python benchmarks/compiled_gather.py [--scene cornell_box] [--resolution 640 480]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import hash_grid  # noqa: E402
from core.context import RenderContext  # noqa: E402
from core.eye_pass import trace_eye_pass  # noqa: E402
from core.photon_pass import DepositTarget, path_dims, trace_photons  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from core.testing.scenes import BUILTIN  # noqa: E402


def recorded_queries(scene, n_paths, settings):
    """The grid and the (positions, normals, directions) of every query of one photon batch."""
    ctx = RenderContext(scene)
    eye = trace_eye_pass(ctx, np.random.default_rng(0), settings.initial_radius_px, settings.max_bounces)
    w, h = scene.camera.resolution
    target = DepositTarget(eye.points, eye.points.base_radius, ctx.table, w * h, ctx.has_shading_normals)
    grid = target.grid
    calls = []
    query = grid.query

    def recording(x, normals, directions=None, inner=False):
        calls.append((x.copy(), normals.copy(), None if directions is None else directions.copy()))
        return query(x, normals, directions, inner=inner)

    grid.query = recording                     # this grid object only
    trace_photons(ctx, target, np.random.default_rng(1).random((n_paths, path_dims(settings.max_bounces))),
                  settings.max_bounces)
    grid.query = query
    return grid, calls


def compiled_query(numba):
    @numba.njit(cache=False)
    def kernel(x, nrm, dirs, origin, cell_size, dims, cell_keys, cell_start, entry_point, entry_pos,
               entry_r2, entry_normal, cos_min, slab2):
        n = x.shape[0]
        cap = 16 * n + 1024
        out_p = np.empty(cap, np.int64)
        out_j = np.empty(cap, np.int64)
        out_c = np.empty(cap, np.float32)
        k = 0
        for i in range(n):
            c0 = int(np.floor((x[i, 0] - origin[0]) / cell_size))
            c1 = int(np.floor((x[i, 1] - origin[1]) / cell_size))
            c2 = int(np.floor((x[i, 2] - origin[2]) / cell_size))
            if c0 < 0 or c1 < 0 or c2 < 0 or c0 >= dims[0] or c1 >= dims[1] or c2 >= dims[2]:
                continue
            key = c0 + dims[0] * (c1 + dims[1] * c2)
            pos = np.searchsorted(cell_keys, key)
            if pos >= cell_keys.shape[0] or cell_keys[pos] != key:
                continue
            rx = np.float32(x[i, 0] - (origin[0] + c0 * cell_size))
            ry = np.float32(x[i, 1] - (origin[1] + c1 * cell_size))
            rz = np.float32(x[i, 2] - (origin[2] + c2 * cell_size))
            for e in range(cell_start[pos], cell_start[pos + 1]):
                dx = entry_pos[0, e] - rx
                dy = entry_pos[1, e] - ry
                dz = entry_pos[2, e] - rz
                if dx * dx + dy * dy + dz * dz >= entry_r2[e]:
                    continue
                if (entry_normal[0, e] * nrm[i, 0] + entry_normal[1, e] * nrm[i, 1]
                        + entry_normal[2, e] * nrm[i, 2]) < cos_min:
                    continue
                h = entry_normal[0, e] * dx + entry_normal[1, e] * dy + entry_normal[2, e] * dz
                if h * h >= slab2 * entry_r2[e]:
                    continue
                if k == cap:
                    cap *= 2
                    out_p = np.concatenate((out_p, np.empty(cap - k, np.int64)))
                    out_j = np.concatenate((out_j, np.empty(cap - k, np.int64)))
                    out_c = np.concatenate((out_c, np.empty(cap - k, np.float32)))
                out_p[k] = i
                out_j[k] = entry_point[e]
                out_c[k] = (entry_normal[0, e] * dirs[i, 0] + entry_normal[1, e] * dirs[i, 1]
                            + entry_normal[2, e] * dirs[i, 2])
                k += 1
        return out_p[:k], out_j[:k], out_c[:k]

    def query(grid, x, normals, directions):
        # (the grid keeps one normal a point since stop 71; the kernel reads a copy per entry,
        # made once per grid)
        entry_normal = getattr(grid, "_entry_normal", None)
        if entry_normal is None:
            entry_normal = grid._entry_normal = np.ascontiguousarray(
                grid.point_normal.take(grid.entry_point, axis=1))
        return kernel(x, normals, normals if directions is None else directions, grid.origin,
                      float(grid.cell_size), grid.dims, grid.cell_keys, grid.cell_start, grid.entry_point,
                      grid.entry_pos, grid.entry_r2, entry_normal, np.float32(hash_grid.NORMAL_COS),
                      np.float32(hash_grid.SLAB ** 2))
    return query


def timed(fn, repeats):
    fn()
    t0 = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - t0) / repeats


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="cornell_box", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(640, 480))
    ap.add_argument("--paths", type=int, default=16384)
    ap.add_argument("--repeats", type=int, default=20)
    a = ap.parse_args()
    try:
        import numba
    except ImportError:
        sys.exit("compiled_gather.py needs numba (pip install numba); it is not a project dependency")
    grid, calls = recorded_queries(BUILTIN[a.scene](resolution=tuple(a.resolution)), a.paths, RenderSettings())
    fast = compiled_query(numba)
    for x, n, d in calls:                      # the same pairs (order within a photon may differ)
        p1, j1, _ = grid.query(x, n, d)
        p2, j2, _ = fast(grid, x, n, d)
        if sorted(zip(p1.tolist(), j1.tolist())) != sorted(zip(p2.tolist(), j2.tolist())):
            sys.exit("the compiled query found other pairs than HashGrid.query")
    vertices = sum(len(c[0]) for c in calls)
    pairs = sum(len(grid.query(*c)[0]) for c in calls)
    candidates = 0
    for x, _, _ in calls:
        keys, _ = grid._cells(x)
        pos = np.minimum(np.searchsorted(grid.cell_keys, keys), len(grid.cell_keys) - 1)
        found = (grid.cell_keys[pos] == keys) & (keys >= 0)
        candidates += int(np.where(found, grid.cell_start[pos + 1] - grid.cell_start[pos], 0).sum())
    t_numpy = timed(lambda: [grid.query(*c) for c in calls], a.repeats)
    t_numba = timed(lambda: [fast(grid, *c) for c in calls], a.repeats)
    print(f"{a.scene} {a.resolution[0]}x{a.resolution[1]}, numba {numba.__version__}: {vertices:,} queried "
          f"vertices, {candidates / vertices:.0f} candidates and {pairs / vertices:.1f} pairs per vertex")
    print(f"NumPy query {1e6 * t_numpy / vertices:6.2f} us per vertex ({1e9 * t_numpy / candidates:5.1f} ns "
          f"per candidate)")
    print(f"Numba query {1e6 * t_numba / vertices:6.2f} us per vertex ({1e9 * t_numba / candidates:5.1f} ns "
          f"per candidate); NumPy / Numba = {t_numpy / t_numba:.2f}")


if __name__ == "__main__":
    main()
