"""What a ``RenderContext`` costs on big meshes, and what of it is embree's.

Every render builds one in the main process and one in each worker, and the 3D viewport's live
render one per edited scene, so on a mesh of millions of triangles it decides how soon the first
image comes.  Two meshes: the Cornell box cut into 4**K times its 34 triangles (``--subdivide``,
corners not shared, as the test scenes' builder makes them) and a grid of N x N squares, two
triangles each, sharing their vertices as Blender's meshes do (``--grid``).  Printed per mesh
(medians of ``--rounds``, the variants alternating): the whole context, ``Scene.bounds``, and
embree's scene built from the triangles' corners (T, 3, 3) against from the vertices and their
indices (V, 3) + (T, 3), with their ratio (the context takes the indices below
``core.accel.SHARED_VERTICES`` vertices per triangle).

    python benchmarks/context_cost.py [--subdivide 8] [--grid 1000] [--rounds 3]
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core.accel import SHARED_VERTICES, _embree_scene  # noqa: E402
from core.context import RenderContext  # noqa: E402
from core.scene import Materials  # noqa: E402
from core.testing.scenes import BUILTIN, subdivide  # noqa: E402


def grid_scene(n, like):
    """``like`` (a Scene) with its geometry replaced by an n x n grid of shared vertices, 4 m wide."""
    u = np.linspace(-2.0, 2.0, n + 1)
    x, y = np.meshgrid(u, u, indexing="ij")
    vertices = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)]).astype(np.float32)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    triangles = np.concatenate([np.stack([i, i + n + 1, i + 1], 1),
                                np.stack([i + 1, i + n + 1, i + n + 2], 1)]).astype(np.int32)
    mats = Materials.build([{"name": "white", "diffuse": 0.8}])
    return dataclasses.replace(like, vertices=vertices, triangles=triangles, materials=mats,
                               material_ids=np.zeros(len(triangles), np.int32), shading_normals=None,
                               uvs=None).validate()


def timed(f):
    t = time.perf_counter()
    f()
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivide", type=int, default=8)
    ap.add_argument("--grid", type=int, default=1000)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    box = BUILTIN["cornell_box"](resolution=(320, 180))
    for name, scene in ((f"cornell_box subdivided {a.subdivide}", subdivide(box, a.subdivide)),
                        (f"grid {a.grid} x {a.grid}", grid_scene(a.grid, box))):
        rel = scene.vertices.astype(np.float64)
        corners = scene.triangle_corners().astype(np.float64)
        times = {"context": [], "bounds": [], "corners": [], "indexed": []}
        for _ in range(a.rounds):
            times["corners"].append(timed(lambda: _embree_scene(corners)))
            times["indexed"].append(timed(lambda: _embree_scene(rel, scene.triangles)))
            times["bounds"].append(timed(scene.bounds))
            times["context"].append(timed(lambda: RenderContext(scene)))
        m = {k: float(np.median(v)) for k, v in times.items()}
        print(f"{name} ({scene.triangle_count:,} triangles, {len(scene.vertices):,} vertices): context "
              f"{m['context']:.2f} s, bounds {m['bounds']:.3f} s; embree's scene from the corners "
              f"{m['corners']:.2f} s, from the vertices and indices {m['indexed']:.2f} s "
              f"(ratio {m['corners'] / m['indexed']:.2f}; the context takes the "
              f"{'indices' if len(rel) < SHARED_VERTICES * scene.triangle_count else 'corners'}; "
              f"median of {a.rounds})", flush=True)


if __name__ == "__main__":
    main()
