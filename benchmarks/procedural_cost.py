"""What a procedural diffuse colour costs the photon pass.

The Cornell box's white material (floor, ceiling, back wall and both boxes: most of what the
photons hit) gets, in turn, a plain colour, a checker, a Noise Texture's Fac through a Color
Ramp, a Noise Texture's Color, and a Voronoi's Color, all on Object coordinates, and an Ambient
Occlusion's Color (16 and 4 rays within 0.5 m, cast at each photon hit); photon paths
are traced into the same eye pass as ``ab_photon_pass.py`` does, the variants alternating
round by round, and the photon vertices per second of each are printed relative to the plain
colour (median and range over rounds, one run).

    python benchmarks/procedural_cost.py [--resolution 320 240] [--rounds 5] [--paths 65536]
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
from core.testing.scenes import with_one_object  # noqa: E402

OBJECT = {"op": "attribute", "name": "object"}
NOISE = {"op": "noise", "vector": OBJECT, "scale": 5.0, "detail": 2.0, "roughness": 0.5, "lacunarity": 2.0}
VARIANTS = {
    "plain": None,
    "checker": {"op": "checker", "vector": OBJECT, "color1": [0.8] * 3, "color2": [0.2] * 3, "scale": 5.0},
    "noise_fac_ramp": {"op": "ramp", "fac": {**NOISE, "output": "Fac"},
                       "table": [[0.1, 0.1, 0.1, 1.0], [0.8, 0.7, 0.6, 1.0]]},
    "noise_color": {**NOISE, "output": "Color"},
    "voronoi_color": {"op": "voronoi", "vector": OBJECT, "scale": 5.0, "output": "Color"},
    # Ambient Occlusion (stop 40): Cycles' default 16 rays within 0.5 m at every photon hit, then 4.
    "ao_16_rays": {"op": "ao", "color": [0.8] * 3, "distance": 0.5, "samples": 16, "output": "Color"},
    "ao_4_rays": {"op": "ao", "color": [0.8] * 3, "distance": 0.5, "samples": 4, "output": "Color"},
}


def cornell_specs(scene):
    """``Materials.build`` entries of the Cornell box's (diffuse or emitting) materials."""
    m = scene.materials
    return [{"name": n, "diffuse": c, "emission": e} for n, c, e in zip(m.names, m.diffuse_color, m.emission)]


def with_program(program):
    """An ``edit`` for ``photon_pass``: the first material's diffuse colour becomes ``program``."""
    def edit(scene):
        if program is None:
            return scene
        specs = cornell_specs(scene)
        specs[0] = {**specs[0], "diffuse_program": program}
        del specs[0]["diffuse"]
        return with_one_object(scene.replace(materials=Materials.build(specs))).validate()
    return edit


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, nargs=2, default=(320, 240))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--paths", type=int, default=65536)
    a = ap.parse_args()
    runs = {name: photon_pass("core", "cornell_box", tuple(a.resolution), a.paths, False, with_program(p))
            for name, p in VARIANTS.items()}
    rates = interleaved_rates(runs, a.rounds)
    plain = np.array(rates["plain"])
    print(f"cornell_box {a.resolution[0]}x{a.resolution[1]}, {a.rounds} rounds of {a.paths} paths: "
          f"plain colour {np.median(plain):,.0f} vertices/s")
    for name in list(runs)[1:]:
        ratio = np.array(rates[name]) / plain
        print(f"  {name}: {np.median(rates[name]):,.0f} vertices/s, {np.median(ratio):.3f} of plain "
              f"(range {ratio.min():.3f}-{ratio.max():.3f})")


if __name__ == "__main__":
    main()
