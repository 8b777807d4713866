"""Cost of absorbing volumes in the photon pass (vertices per second, one process).

A built-in scene is traced as it is and with every glass material given an absorbing volume
(``Materials.volume_absorption``, 0.1 per unit: the paths hardly change, the machinery runs:
the volume each path is in, the absorption of every segment, the probe that finds the lights'
volumes), alternately on the same eye pass and random numbers, so each round's ratio shares the
machine load (median and range over rounds).  Scenes without glass get the volume on their first
material.  A scene without volumes runs none of it (``RenderContext.has_volumes``); what that
costs against the code before volumes is ``ab_photon_pass.py --base 52c98b4``.  With
``--scattering`` the volumes scatter 0.1 per unit instead (the distances drawn in every
segment, photons stopping and scattering in them, their deposits on the volume points of the
eye pass): vertices in volumes count as vertices.

    python benchmarks/volume_cost.py [--scene glass_ceiling_room] [--resolution 320 240]
                                     [--rounds 5] [--paths 65536] [--pairs] [--scattering]
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core.testing.scenes import BUILTIN  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ab_photon_pass import interleaved_rates, photon_pass  # noqa: E402


def with_volumes(scene, field="volume_absorption"):
    """``scene`` with its glass (or, without glass, its first material) absorbing (or with
    ``field`` "volume_scattering", scattering) 0.1 per unit."""
    m = scene.materials
    glass = m.dielectric_weight > 0
    if not glass.any():
        glass[0] = True
    getattr(m, field)[glass] = 0.1
    return scene.validate()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="glass_ceiling_room", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(320, 240))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--paths", type=int, default=65536)
    ap.add_argument("--pairs", action="store_true", help="collect deposit pairs (as the chains do)")
    ap.add_argument("--scattering", action="store_true", help="volumes that scatter instead of absorbing")
    a = ap.parse_args()
    res = tuple(a.resolution)
    field = "volume_scattering" if a.scattering else "volume_absorption"
    runs = {"plain": photon_pass("core", a.scene, res, a.paths, a.pairs),
            "volumes": photon_pass("core", a.scene, res, a.paths, a.pairs,
                                   edit=lambda scene: with_volumes(scene, field))}
    rates = interleaved_rates(runs, a.rounds)
    r = np.array(rates["volumes"]) / np.array(rates["plain"])
    print(f"{a.scene} {res[0]}x{res[1]}, {a.paths} paths, {a.rounds} rounds{', pairs' if a.pairs else ''}: "
          f"plain {np.median(rates['plain']) / 1e3:.1f} k vertices/s, with volumes "
          f"{np.median(rates['volumes']) / 1e3:.1f} k; volumes / plain {np.median(r):.3f} "
          f"({r.min():.3f}-{r.max():.3f})")


if __name__ == "__main__":
    main()
