"""Which numbers a pixel's light samples should take, in a simulation (no render).

Each of many pixels (each its own random bits) takes ``passes`` passes of ``samples`` light samples,
a pass's pixel point from the stratified jitter (``core.camera.stratified_jitter``: Sobol's first
two dimensions at the pass index, shifted per pixel) and each sample four numbers y (the emitter's
choice, the point on the light, one more).  Integrands of the pixel point x and the sample y stand
for what a light sample estimates: a penumbra that moves across the pixel (``edge``, ``slanted
edge``), the part of an area light a point sees (``disc on the light``), a choice between two
emitters (``choice``) and a smooth falloff (``smooth``).  Their exact means come from 4 million
independent points; the script prints each scheme's RMS error over the pixels:

- ``random``: independent numbers (``pixel_jitter="random"``'s light samples);
- ``sobol 8-11``: Sobol's dimensions 8 to 11 at index pass * samples + sample, shifted per pixel
  (one sequence with the jitter's, lens's and lobes' dimensions 1 to 7);
- ``owen index, shifted``: the choice of Sobol's dimension 3, the point of its dimensions 1 and 2
  and the last of 4, at that index Owen-scrambled per pixel (``core.sampling.owen_scramble``), the
  coordinates shifted per pixel;
- ``owen index and values``: the same with the coordinates Owen-scrambled per pixel instead
  (``core.direct.stratified_light``, the renderer's; Cycles' Sobol-Burley).

Each row's ratios to ``random`` are summed up at the end (geometric means and the worst).

    python benchmarks/light_numbers.py [--pixels 4000] [--seed 1]
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from core import sampling as smp  # noqa: E402
from core.camera import stratified_jitter  # noqa: E402
from core.direct import stratified_light  # noqa: E402

INTEGRANDS = {
    "edge": lambda x, y: (x[..., 0] + y[..., 1] < 1.0).astype(float),
    "slanted edge": lambda x, y: (0.3 * x[..., 0] + 0.7 * y[..., 2] + 0.2 * x[..., 1] < 0.6).astype(float),
    "disc on the light": lambda x, y: ((y[..., 1] - 0.5) ** 2 + (y[..., 2] - 0.4) ** 2 < 0.1).astype(float),
    "choice": lambda x, y: np.where(y[..., 0] < 0.3, 2.0 * y[..., 1], (y[..., 2] > x[..., 1]).astype(float)),
    "smooth": lambda x, y: np.cos(3 * x[..., 0] + 2 * y[..., 1] - y[..., 2]) + y[..., 3] * y[..., 2],
}


def schemes(rng, salt, pixels, passes, samples):
    """{name: (pixels, passes * samples, 4) numbers} for the light samples."""
    n = np.arange(passes * samples, dtype=np.uint64)
    shift = rng.integers(0, 2 ** 32, (pixels, 1, 4), dtype=np.uint64)
    seeds = rng.integers(0, 2 ** 32, (pixels, 1), dtype=np.uint64)
    index = smp.owen_scramble(np.broadcast_to(n, (pixels, len(n))), np.broadcast_to(seeds, (pixels, len(n))))
    scrambled = smp.sobol_points(index.ravel(), (3, 1, 2, 4)).reshape(pixels, len(n), 4)
    rows, sample = np.repeat(np.arange(pixels), samples), np.tile(np.arange(samples), pixels)
    ours = np.stack([stratified_light(salt, k, samples, np.arange(pixels) * 64)(rows, sample)
                     .reshape(pixels, samples, 4) for k in range(passes)], axis=1).reshape(pixels, -1, 4)
    return {"random": rng.random((pixels, len(n), 4)),
            "sobol 8-11": (smp.sobol_points(n, (8, 9, 10, 11))[None] ^ shift).astype(np.float64) * 2.0 ** -32,
            "owen index, shifted": (scrambled ^ shift).astype(np.float64) * 2.0 ** -32,
            "owen index and values": ours}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pixels", type=int, default=4000)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    u = rng.random((4_000_000, 6))
    exact = {name: f(u[:, :2], u[:, 2:]).mean() for name, f in INTEGRANDS.items()}
    print(f"RMS error over {a.pixels:,} pixels (each pass's pixel point stratified_jitter's)")
    print("| samples a pass | passes | scheme | " + " | ".join(INTEGRANDS) + " |")
    print("|---|---|---|" + "---|" * len(INTEGRANDS))
    ratios = {}
    for samples in (1, 4):
        for passes in (4, 16, 64):
            x = np.stack([stratified_jitter(a.seed, k, np.arange(a.pixels)) for k in range(passes)], axis=1)
            x = np.repeat(x, samples, axis=1)
            errors = {name: np.array([np.sqrt(np.mean((f(x, y).mean(axis=1) - exact[k]) ** 2))
                                      for k, f in INTEGRANDS.items()])
                      for name, y in schemes(rng, a.seed + 7, a.pixels, passes, samples).items()}
            for name, e in errors.items():
                cells = " | ".join(f"{v:.4f}" for v in e)
                print(f"| {samples} | {passes} | {name} | {cells} |", flush=True)
                ratios.setdefault(name, {}).setdefault(samples, []).append(e / errors["random"])
    print("\nRMS error / random's: geometric mean over integrands and passes (1 sample a pass; 4), the worst")
    for name, by in list(ratios.items())[1:]:
        one, four = np.array(by[1]), np.array(by[4])
        print(f"{name}: {np.exp(np.log(one).mean()):.2f}; {np.exp(np.log(four).mean()):.2f}, worst "
              f"{max(one.max(), four.max()):.2f}")


if __name__ == "__main__":
    main()
