"""Cost of Principled's Fresnel layer, of metals' Fresnel curve and of translucency in the photon
pass (vertices per second, one process).

Every diffuse material of a built-in scene is given one of these bases, and all are traced
alternately on the same eye pass and random numbers, so each round's ratios share the machine
load (median and range over rounds):

* ``diffuse``: the scene as it is;
* ``constant``: the earlier Principled mapping, a white GGX lobe (roughness 0.5, multiscatter)
  of weight 0.092 (mean Fresnel of IOR 1.5) over the diffuse of weight 0.908;
* ``layered``: Cycles' layering, a GGX lobe reflecting 0.04 + 0.96 s(c) (``glossy_fresnel_*``)
  over the whole diffuse, whose weight follows the layer's albedo at the view
  (``diffuse_layer``);
* ``metal``: a gold-like metal of roughness 0.5 coloured by its F82 curve's mean (how metals were
  exported before their curve: ``bsdf.metal_fresnel``);
* ``metal_curve``: the same metal with its curve by angle (``glossy_metal_rise`` and ``_dip``);
* ``metal_brushed``: that metal anisotropic (``glossy_stretch`` 3, Blender's default radial
  tangent from the Generated coordinates of one object around the scene): a tangent at every
  hit, the anisotropic sampler and the anisotropic deposit kernel;
* ``translucent``: half of the diffuse colour reflected, half let through (a Mix of a Diffuse
  and a Translucent BSDF by 0.5 of one colour): a fifth lobe, photons that scatter through the
  surface, and a second grid query for every photon that lands on it (the points on its other
  side: in a closed room none, so this is the price of looking);
* ``translucent_one``: the same for the last diffuse material alone (the Cornell box's green
  wall): the second query then looks among the translucent points alone (``back_grid``);
* ``rough_diffuse``: every diffuse material of roughness 1 (Cycles' Oren-Nayar with its energy
  compensation, ``bsdf.rough_diffuse_factor``, per sample and per deposit pair).

``translucent / diffuse`` is the price of translucency everywhere, ``translucent_one / diffuse`` on
one wall, ``rough_diffuse / diffuse`` that of diffuse roughness; ``metal_curve / metal`` is the
price of the curve (a colour per deposit pair and per sample), ``metal_brushed / metal_curve``
that of anisotropy; ``layered / constant`` is the price of the Fresnel machinery (rise per
sample and per deposit pair, layer factor per diffuse sample and per point); ``constant /
diffuse`` that of a glossy lobe at all.

A second part times the glossy deposit kernel alone on random pairs: ``bsdf.eval_glossy``
(frame-free, cosines of the half vector only) against the earlier form that rotated both
directions into a local frame first (``to_local`` + ``ggx_reflection_f``), alternately in the
same rounds.

    python benchmarks/layer_cost.py [--scene cornell_box] [--resolution 320 240] [--rounds 5]
                                    [--paths 65536] [--pairs] [--eval-pairs 1000000]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import sampling as smp  # noqa: E402
from core.bsdf import eval_glossy, metal_curve, metal_fresnel  # noqa: E402
from core.testing.scenes import BUILTIN, with_one_object  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ab_photon_pass import interleaved_rates, photon_pass  # noqa: E402

VARIANTS = ("diffuse", "constant", "layered", "metal", "metal_curve", "metal_brushed", "translucent",
            "translucent_one", "rough_diffuse")
GOLD, GOLD_TINT = np.array([0.9, 0.6, 0.3]), np.array([1.0, 0.8, 0.6])


def with_base(scene, variant):
    """``scene`` with the diffuse materials given the ``variant`` base (see the module docstring)."""
    if variant == "diffuse":
        return scene
    m = scene.materials
    on = (m.diffuse_weight > 0) & (m.glossy_weight == 0) & ~(m.emission > 0).any(axis=1)
    m.glossy_roughness[on] = 0.5
    if variant == "rough_diffuse":
        m.diffuse_roughness[on] = 1.0
    elif variant.startswith("translucent"):
        if variant == "translucent_one":
            on = np.arange(len(on)) == np.flatnonzero(on)[-1]
        m.diffuse_weight[on] *= 0.5
        m.translucent_weight[on] = m.diffuse_weight[on]
        m.translucent_color[on] = m.diffuse_color[on]
    elif variant.startswith("metal"):
        f0, rise, dip = metal_curve(GOLD, GOLD_TINT)
        m.diffuse_weight[on] = 0.0
        m.glossy_weight[on] = 1.0
        m.glossy_color[on] = metal_fresnel(GOLD, GOLD_TINT) if variant == "metal" else f0
        m.glossy_multiscatter[on] = metal_fresnel(GOLD, GOLD_TINT)
        if variant != "metal":
            m.glossy_metal_rise[on] = rise
            m.glossy_metal_dip[on] = dip
        if variant == "metal_brushed":
            m.glossy_stretch[on] = 3.0
            lo, hi = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
            scene = with_one_object(scene, (0.5 * (lo + hi), 0.5 * (hi - lo)))
    elif variant == "constant":
        m.diffuse_weight[on] = 0.908
        m.glossy_weight[on] = 0.092
        m.glossy_color[on] = 1.0
        m.glossy_multiscatter[on] = 1.0
    else:
        m.glossy_weight[on] = m.diffuse_weight[on]
        m.glossy_color[on] = 0.04
        m.glossy_fresnel_ior[on] = 1.5
        m.glossy_fresnel_rise[on] = 0.96
        m.diffuse_layer[on] = 0.04
        m.glossy_multiscatter[on] = 0.1
    return scene.validate()


def eval_kernels(n, rng):
    """Two timed callables evaluating GGX on the same ``n`` random pairs (see the docstring)."""
    ns = smp.normalize(rng.normal(size=(n, 3)))
    wo = smp.to_world(smp.cosine_hemisphere(rng.random(n), rng.random(n)), ns)
    wi = smp.to_world(smp.cosine_hemisphere(rng.random(n), rng.random(n)), ns)
    alpha = np.full(n, 0.25)

    def frame_free():
        return eval_glossy(alpha, wo, wi, ns)

    def local_frame():
        return smp.ggx_reflection_f(smp.to_local(wo, ns), smp.to_local(wi, ns), alpha)
    assert np.allclose(frame_free(), local_frame(), rtol=1e-9, atol=1e-12)
    return {"frame-free": frame_free, "local frame": local_frame}


def timed(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="cornell_box", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(320, 240))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--paths", type=int, default=65536)
    ap.add_argument("--pairs", action="store_true", help="collect deposit pairs (as the chains do)")
    ap.add_argument("--eval-pairs", type=int, default=1_000_000, help="pairs of the eval_glossy timing")
    a = ap.parse_args()
    runs = {v: photon_pass("core", a.scene, tuple(a.resolution), a.paths, a.pairs,
                           edit=lambda scene, v=v: with_base(scene, v)) for v in VARIANTS}
    rates = interleaved_rates(runs, a.rounds)
    print(f"{a.scene} {a.resolution[0]}x{a.resolution[1]}, {a.paths} paths, {a.rounds} rounds"
          f"{', pairs' if a.pairs else ''}")
    for v in VARIANTS:
        print(f"  {v:15s} {np.median(rates[v]) / 1e3:8.1f} k vertices/s")
    for num, den in (("layered", "constant"), ("constant", "diffuse"), ("layered", "diffuse"),
                     ("metal_curve", "metal"), ("metal_brushed", "metal_curve"), ("translucent", "diffuse"),
                     ("translucent_one", "diffuse"),
                     ("rough_diffuse", "diffuse")):
        r = np.array(rates[num]) / np.array(rates[den])
        print(f"  {num} / {den}: {np.median(r):.3f} ({r.min():.3f}-{r.max():.3f})")

    kernels = eval_kernels(a.eval_pairs, np.random.default_rng(2))
    times = {k: [] for k in kernels}
    for _ in range(a.rounds):
        for k, fn in kernels.items():
            times[k].append(timed(fn))
    r = np.array(times["local frame"]) / np.array(times["frame-free"])
    print(f"eval_glossy on {a.eval_pairs} pairs: frame-free {np.median(times['frame-free']) * 1e3:.0f} ms, "
          f"local frame {np.median(times['local frame']) * 1e3:.0f} ms; "
          f"speed-up {np.median(r):.2f} ({r.min():.2f}-{r.max():.2f})")


if __name__ == "__main__":
    main()
