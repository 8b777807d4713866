"""Cost of shadow catchers (``SHADOW_CATCHER``, ``core/shadow_catcher.py``): the same scene with its
floor a catcher against the floor as it is, with the Shadow Catcher pass asked for.

A catcher costs the eye pass's marks and sums and a photon pass at the main render's points on
the catchers in a scene of the catchers and emitters (``CatcherRender``), in the main process, as
many photons as the main render's per worker (and an eye pass for paths through a mirror or glass
catcher), and with the Markov chains the same uniform photons once more in the main scene (the
shadow's numerator).  The floor: the triangles facing up at the scene's lowest height
(``core.testing.scenes.floor_catchers``).  Measured as ``light_passes_cost.py`` measures, without
the catcher and with it alternating in every round.

    python benchmarks/shadow_catcher_cost.py [--scenes cornell_box glass_ceiling_room sky_over_floor]
                                             [--resolution 320 240] [--rounds 3] [--passes 3]
                                             [--time-limit S]

With ``--time-limit S`` it renders each scene with its floor a catcher under that time limit instead
(PPM and the chains, one and two workers) and prints the time taken over the limit, the passes, the
main render's photons and the catchers' render's (``catcher_photons`` of the pass statistics; stop
56 traces a pass once there, after the main one, and leaves it its share of the time left).
"""
from __future__ import annotations

import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import render  # noqa: E402
from core.settings import RenderSettings  # noqa: E402
from core.testing.scenes import BUILTIN, floor_catchers, sky_over_floor  # noqa: E402
from light_passes_cost import compare  # noqa: E402  (this folder is first on sys.path)

SCENES = {**BUILTIN, "sky_over_floor": lambda resolution: sky_over_floor(resolution=resolution)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+",
                        default=["cornell_box", "glass_ceiling_room", "sky_over_floor"])
    parser.add_argument("--resolution", nargs=2, type=int, default=[320, 240])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--passes", type=int, default=3)
    parser.add_argument("--time-limit", type=float, default=None)
    args = parser.parse_args()
    size = f"{args.resolution[0]}x{args.resolution[1]}"
    if args.time_limit is not None:
        for name in args.scenes:
            caught, count = floor_catchers(SCENES[name](tuple(args.resolution)))
            for method in ("ppm", "amcmcppm"):
                for workers in (1, 2):
                    settings = RenderSettings(time_limit=args.time_limit, workers=workers, method=method,
                                              data_passes=("shadow_catcher",))
                    r = render(caught, settings)
                    main = sum(st["photons_recorded"] for st in r.stats)
                    k = sum(st.get("catcher_photons", 0) for st in r.stats)
                    print(f"{name} {size} {method} workers {workers}, limit {args.time_limit:g} s: "
                          f"took {r.elapsed_s / args.time_limit:.3f} of it, {r.passes} passes, "
                          f"{main:,} main photons, {k:,} in the catchers' render", flush=True)
        return
    for name in args.scenes:
        plain = SCENES[name](tuple(args.resolution))
        caught, count = floor_catchers(plain)
        for method in ("ppm", "amcmcppm"):
            def run(scene, seed=0):
                settings = RenderSettings(passes=args.passes, workers=1, seed=seed, method=method,
                                          data_passes=("shadow_catcher",))
                return lambda: render(scene, settings)
            compare(f"{name} {size} {method}, {args.passes} passes, floor of {count} triangles a catcher",
                    run, (plain, caught), args.rounds)

if __name__ == "__main__":
    main()
