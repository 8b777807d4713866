"""What Ambient Occlusion's Only Local costs as the objects multiply.

Only Local (and Bevel) query each hit's own object: until stop 41 one Embree scene per object and
a loop in Python over the objects a batch of hits touched, now one scene of every object shifted
apart (``core.accel.LocalScene``).  This measures it where the objects are many: the town of
``small_view`` with 100, 1,000 and 4,000 buildings, each its own object, whose colour is Ambient
Occlusion (4 rays within 2 m) cast at every photon hit, against the same AO over the whole scene
and against a plain colour; photon paths are traced into one eye pass as ``ab_photon_pass.py``
does, the variants alternating round by round.  Printed: photon vertices per second, and Only
Local's rate over the whole scene's (median and range over rounds, one run).

    python benchmarks/local_queries_cost.py [--boxes 100 1000 4000] [--rounds 3] [--paths 16384]
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from ab_photon_pass import interleaved_rates, photon_pass  # noqa: E402

from core.scene import Materials  # noqa: E402
from core.testing import scenes  # noqa: E402

AO = {"op": "ao", "color": [0.7, 0.6, 0.5], "distance": 2.0, "samples": 4, "output": "Color"}


def town(boxes, program):
    """A ``photon_pass`` scene maker: ``small_view`` with ``boxes`` buildings, each its own object
    (the ground, the clearing and the ball three more), the buildings' colour ``program`` (None:
    their plain colour)."""
    def make(resolution):
        scene = scenes.small_view(resolution=resolution, boxes=boxes)
        tris = scene.triangle_count
        ids = np.zeros(tris, np.int32)
        ids[2:2 + 12 * boxes] = 1 + np.arange(12 * boxes) // 12          # (12 triangles a box)
        ids[2 + 12 * boxes:2 + 12 * boxes + 12] = boxes + 1
        ids[2 + 12 * boxes + 12:] = boxes + 2
        n = boxes + 3
        specs = [{"name": "ground", "diffuse": (0.5, 0.5, 0.45)},
                 {"name": "building", **({"diffuse": (0.7, 0.6, 0.5)} if program is None
                                         else {"diffuse_program": program})},
                 {"name": "glass", "dielectric": 1.0, "ior": 1.5}]
        return scene.replace(materials=Materials.build(specs), object_ids=ids,
                             object_from_world=np.tile(np.eye(3, 4), (n, 1, 1)),
                             texture_spaces=np.tile([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], (n, 1, 1)),
                             object_info=np.zeros((n, 6), np.float32)).validate()
    return make


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boxes", type=int, nargs="+", default=(100, 1000, 4000))
    ap.add_argument("--resolution", type=int, nargs=2, default=(160, 120))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--paths", type=int, default=16384)
    a = ap.parse_args()
    resolution = tuple(a.resolution)
    for boxes in a.boxes:
        variants = {"plain": None, "ao_whole_scene": AO, "ao_only_local": {**AO, "only_local": True}}
        runs = {}
        for name, program in variants.items():
            make = town(boxes, program)
            runs[name] = photon_pass("core", "small_view", resolution, a.paths, False,
                                     edit=lambda _scene, make=make: make(resolution))
        rates = interleaved_rates(runs, a.rounds)
        whole, local = np.array(rates["ao_whole_scene"]), np.array(rates["ao_only_local"])
        ratio = local / whole
        print(f"small_view with {boxes} buildings (objects), {a.rounds} rounds of {a.paths} paths: "
              f"plain {np.median(rates['plain']):,.0f}, AO over the whole scene {np.median(whole):,.0f}, "
              f"Only Local {np.median(local):,.0f} vertices/s; Only Local / whole scene "
              f"{np.median(ratio):.3f} (range {ratio.min():.3f}-{ratio.max():.3f})")


if __name__ == "__main__":
    main()
