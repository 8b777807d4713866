"""What evaluating procedural programs in chunks saves (``core.procedural.EVAL_CHUNK``).

Programs of the kind artists put in a world or a material (a Noise Texture's Color at detail 15,
its Fac at detail 2, a Voronoi's Color, a checker) are evaluated over the directions of a world's
bake (1024 x 512: what the exporter does for a procedural world) with ``EVAL_CHUNK`` set to each
size asked for (``0``: all at once, as before chunks), sizes alternating round by round; medians of
the seconds and their ratio to all at once (and a check that every size gives the same values).
With ``--eye W H`` the same for eye passes of the Cornell box at W x H whose white material (most
of what the camera sees) takes the program as its diffuse colour:

    python benchmarks/eval_chunk.py [--width 1024] [--chunks 0 16384 65536 262144] [--rounds 3]
                                    [--programs ...] [--eye W H]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from ab_photon_pass import first_eye_pass  # noqa: E402
from procedural_cost import with_program  # noqa: E402

from core import procedural  # noqa: E402
from core.environment import equirectangular_directions  # noqa: E402

GENERATED = {"op": "attribute", "name": "generated"}
PROGRAMS = {
    "noise_detail_15_color": {"op": "noise", "vector": GENERATED, "scale": 5.0, "detail": 15.0,
                              "roughness": 0.5, "lacunarity": 2.0, "output": "Color"},
    "noise_detail_2_fac": {"op": "noise", "vector": GENERATED, "scale": 5.0, "detail": 2.0,
                           "roughness": 0.5, "lacunarity": 2.0, "output": "Fac"},
    "voronoi_color": {"op": "voronoi", "vector": GENERATED, "scale": 5.0, "output": "Color"},
    "checker": {"op": "checker", "vector": GENERATED, "color1": [0.8] * 3, "color2": [0.2] * 3, "scale": 5.0},
    "gabor_3d": {"op": "gabor", "vector": GENERATED, "gabor_type": "3D", "scale": 5.0, "frequency": 2.0,
                 "anisotropy": 1.0, "output": "Value"},
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=1024, help="the bake's width (height: half)")
    ap.add_argument("--chunks", type=int, nargs="+", default=(0, 16384, 65536, 262144))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--programs", nargs="+", default=list(PROGRAMS), choices=list(PROGRAMS))
    ap.add_argument("--eye", type=int, nargs=2, default=None, metavar=("W", "H"))
    args = ap.parse_args()
    if args.eye:
        print(f"eye passes of the Cornell box at {args.eye[0]} x {args.eye[1]}; medians of {args.rounds} "
              "rounds")
    else:
        dirs = equirectangular_directions(args.width, args.width // 2).reshape(-1, 3)
        attrs = procedural.DirectionAttributes(dirs)
        print(f"{len(dirs)} directions; medians of {args.rounds} rounds (seconds, and / all at once)")
    names = ("all at once" if c == 0 else f"chunks of {c}" for c in args.chunks)
    print("| program | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(args.chunks))
    for name in args.programs:
        seconds = {c: [] for c in args.chunks}
        reference = None
        if args.eye:
            trace = first_eye_pass("core", "cornell_box", tuple(args.eye), with_program(PROGRAMS[name]))[3]
        for r in range(args.rounds):
            for c in (args.chunks if r % 2 == 0 else args.chunks[::-1]):
                procedural.EVAL_CHUNK = c if c > 0 else 1 << 40
                t0 = time.perf_counter()
                value = trace().points.colors if args.eye else procedural.evaluate(PROGRAMS[name], attrs, [])
                seconds[c].append(time.perf_counter() - t0)
                if reference is None:
                    reference = value
                elif not np.array_equal(value, reference):
                    raise SystemExit(f"{name}: chunks of {c} changed the values")
        base = np.median(seconds[args.chunks[0]])
        print(f"| {name} | " + " | ".join(f"{np.median(s):.3f} ({np.median(s) / base:.2f})"
                                           for s in seconds.values()) + " |", flush=True)


if __name__ == "__main__":
    main()
