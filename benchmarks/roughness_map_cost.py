"""What a roughness map (or an anisotropy map) costs: the material table's build and the photon pass.

The Cornell box's white material (floor, ceiling, back wall and both boxes) becomes a Principled-
like dielectric (a diffuse base under a specular layer of IOR 1.5, multiscatter GGX) of constant
roughness 0.4, then of a roughness map (a Noise Texture's Fac through a ramp from 0.1 to 0.7, on
Object coordinates).  Printed: the time to build the render context (the map's material is
copied at ``bsdf.ROUGHNESS_LEVELS`` roughness levels, each with its albedo and layer tables;
median of ``--rounds``) and the photon vertices per second of the map relative to the constant
(rounds alternating, median and range; one run).  ``--kind anisotropy``: the white material
becomes a brushed metal instead (F82 gold, roughness 0.4, radial tangent) of constant stretch 2, then
of an anisotropy map (the same noise through a ramp from stretch 1 to 4; the material is copied at
``bsdf.STRETCH_LEVELS`` stretches, which share their tables).  ``--kind metal``: the white material
becomes a rough (0.4) metal whose base colour is the same noise through a ramp from copper to
silver, first with the F82 curve's mean per point as its colour (the ``metal`` program: the
"constant" row, as before stop 37), then with the curve of each hit's F0
(``Materials.glossy_metal_tint``: the "map" row).  ``--kind metallic``: the white material becomes a
Principled BSDF of that base colour and the roughness map whose Metallic is another noise, first as
the exporter made it before stop 38 (one row: the node at 0 and 1 mixed by the map's mean, the diffuse
colour point by point), then as now (that row picks one of 17 levels of Metallic at each hit, one of
the two around the map's value by the fraction between them, ``Materials.level_program``; each
level has the roughness map, so 17 x 65 copies).  ``--kind mask``: the white material becomes a Mix
Shader of a Principled paint (a blue-to-white noise base colour) and that copper-to-silver metal (both
of roughness 0.4) by a noise mask, first as one row of the mask's mean (the "constant" row), then
with the 17 levels of the mask as the exporter makes them: each level's diffuse colour is the
paint's noise, one program for all ("map"), or as the exporter made it before stop 39, the noise
times (1 - k) w divided by (1 - k) w, a different program at each level ("distinct", evaluated
once per level present in a batch).

    python benchmarks/roughness_map_cost.py [--kind roughness|anisotropy|metal|metallic|mask]
        [--resolution 320 240]
        [--rounds 5] [--paths 65536]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from ab_photon_pass import interleaved_rates, photon_pass  # noqa: E402
from procedural_cost import cornell_specs  # noqa: E402

from core.context import RenderContext  # noqa: E402
from core.scene import Materials  # noqa: E402
from core.testing.scenes import BUILTIN, with_one_object  # noqa: E402

OBJECT = {"op": "attribute", "name": "object"}
NOISE = {"op": "noise", "vector": OBJECT, "scale": 5.0, "detail": 2.0, "roughness": 0.5, "lacunarity": 2.0,
         "output": "Fac"}
ROUGHNESS_MAP = {"op": "map_range", "value": NOISE, "from_min": 0.0, "from_max": 1.0, "to_min": 0.1,
                 "to_max": 0.7}
LAYER = {"glossy": 0.04, "glossy_fresnel_ior": 1.5, "glossy_fresnel_rise": 0.96, "diffuse_layer": 0.04}
BRUSHED = {"glossy": [1.0, 0.78, 0.34], "glossy_metal_rise": [0.0, 0.22, 0.66], "glossy_multiscatter": 0.0,
           "roughness": 0.4, "glossy_stretch": 2.0}
STRETCH_MAP = dict(ROUGHNESS_MAP, to_min=1.0, to_max=4.0)


def with_layer(roughness_map):
    """An ``edit`` for ``photon_pass``: the first material gets the specular layer, of roughness 0.4
    or of ``ROUGHNESS_MAP``."""
    def edit(scene):
        specs = cornell_specs(scene)
        specs[0] = {**specs[0], **LAYER, "roughness": 0.4}
        if roughness_map:
            specs[0]["roughness_program"] = ROUGHNESS_MAP
        return with_one_object(scene.replace(materials=Materials.build(specs))).validate()
    return edit


def brushed(stretch_map):
    """An ``edit`` for ``photon_pass``: the first material becomes a brushed metal of stretch 2 or
    of ``STRETCH_MAP``."""
    def edit(scene):
        specs = cornell_specs(scene)
        specs[0] = {"name": specs[0].get("name", "white"), **BRUSHED}
        if stretch_map:
            specs[0]["stretch_program"] = STRETCH_MAP
        return with_one_object(scene.replace(materials=Materials.build(specs))).validate()
    return edit


COPPER_TO_SILVER = {"op": "mix_color", "fac": NOISE, "a": [0.95, 0.6, 0.2], "b": [0.9, 0.9, 0.92]}
METAL_TINT = [1.0, 0.8, 0.6]


def textured_metal(per_hit):
    """An ``edit`` for ``photon_pass``: the first material becomes a rough metal of base colour
    ``COPPER_TO_SILVER``, with the curve's mean per point or (``per_hit``) the curve of each hit."""
    def edit(scene):
        specs = cornell_specs(scene)
        specs[0] = {"name": specs[0].get("name", "white"), "glossy": 1.0, "roughness": 0.4,
                    "glossy_multiscatter": 1.0}
        if per_hit:
            specs[0].update(glossy_program=COPPER_TO_SILVER, glossy_metal_tint=METAL_TINT)
        else:
            specs[0]["glossy_program"] = {"op": "metal", "color": COPPER_TO_SILVER, "tint": METAL_TINT}
        return with_one_object(scene.replace(materials=Materials.build(specs))).validate()
    return edit


METALLIC_MAP = {"op": "map_range", "value": dict(NOISE, scale=2.5), "from_min": 0.35, "from_max": 0.65,
                "to_min": 0.0, "to_max": 1.0, "clamp": True}


def principled_at(metallic, name, diffuse=COPPER_TO_SILVER, roughness=ROUGHNESS_MAP):
    """The core's row of a Principled BSDF of base colour ``COPPER_TO_SILVER``, ``ROUGHNESS_MAP``, IOR 1.5
    and Metallic ``metallic`` (as the exporter makes it, untinted specular, multiscatter GGX); its
    diffuse colour ``diffuse`` instead (a mask's level between a paint and a metal), its roughness the
    float program ``roughness`` (None: 0.4)."""
    k = metallic
    spec = {"name": name, "diffuse_weight": 1.0 - k, "diffuse_program": diffuse, "glossy": 1.0,
            "roughness": 0.4, "diffuse_layer": 0.04,
            "glossy_fresnel_ior": 1.5, "glossy_fresnel_rise": (1.0 - k) * 0.96, "glossy_multiscatter": 0.09}
    if roughness is not None:
        spec["roughness_program"] = roughness
    if k >= 1.0:
        spec.update(glossy_fresnel_ior=0.0, glossy_fresnel_rise=0.0, glossy_multiscatter=1.0)
    if k > 0:
        f0 = {"op": "mix_color", "fac": 0.0, "a": COPPER_TO_SILVER, "b": [0.0, 0.0, 0.0],
              "clamp_result": True}
        spec.update(glossy_program=f0, glossy_metal_tint=METAL_TINT)
        if k < 1.0:
            spec.update(glossy_metal_share=k, glossy_metal_rest=(1.0 - k) * 0.04)
    else:
        spec["glossy"] = 0.04
    return spec


def metallic_map(levels):
    """An ``edit`` for ``photon_pass``: the first material becomes a Principled BSDF with a metallic map,
    without (the mean, as before) or with its 17 levels."""
    def edit(scene):
        specs = cornell_specs(scene)
        name = specs[0].get("name", "white")
        mean = principled_at(0.5, name)          # (the map's mean: about 0.5)
        mean.update(glossy=0.5 * 0.04 + 0.5 * 0.7, glossy_fresnel_rise=0.48, glossy_multiscatter=0.5)
        for key in ("glossy_program", "glossy_metal_tint", "glossy_metal_share", "glossy_metal_rest"):
            del mean[key]
        specs[0] = mean
        if levels:
            first = len(specs)
            specs[0].update(level_program=METALLIC_MAP, level_first=first, level_count=17)
            specs += [principled_at(k, f"{name} {k}") for k in np.linspace(0.0, 1.0, 17)]
        return with_one_object(scene.replace(materials=Materials.build(specs))).validate()
    return edit


PAINT = {"op": "mix_color", "fac": dict(NOISE, scale=9.0), "a": [0.1, 0.2, 0.6], "b": [0.9, 0.9, 0.9]}


def masked(levels):
    """An ``edit`` for ``photon_pass``: the first material becomes a Mix Shader of ``PAINT`` and the
    textured metal by a noise mask: its mean (``levels`` None), or its 17 levels, each diffuse colour
    one program (``"map"``) or a program of its own (``"distinct"``)."""
    def edit(scene):
        specs = cornell_specs(scene)
        name = specs[0].get("name", "white")
        mean = principled_at(0.5, name, PAINT, None)
        mean.update(glossy=0.5 * 0.04 + 0.5 * 0.7, glossy_fresnel_rise=0.48, glossy_multiscatter=0.5)
        for key in ("glossy_program", "glossy_metal_tint", "glossy_metal_share", "glossy_metal_rest"):
            del mean[key]
        specs[0] = mean
        if levels is not None:
            first = len(specs)
            specs[0].update(level_program=METALLIC_MAP, level_first=first, level_count=17)
            for k in np.linspace(0.0, 1.0, 17):
                diffuse = PAINT
                if levels == "distinct" and 0 < k < 1:
                    w = [(1.0 - k) * 1.0] * 3
                    scaled = {"op": "mix_color", "blend": "MULTIPLY", "fac": 1.0, "a": PAINT, "b": w}
                    diffuse = {"op": "mix_color", "blend": "MULTIPLY", "fac": 1.0, "a": scaled,
                               "b": [1.0 / w[0]] * 3}
                specs.append(principled_at(k, f"{name} {k}", diffuse, None))
        return with_one_object(scene.replace(materials=Materials.build(specs))).validate()
    return edit


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", choices=("roughness", "anisotropy", "metal", "metallic", "mask"),
                    default="roughness")
    ap.add_argument("--resolution", type=int, nargs=2, default=(320, 240))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--paths", type=int, default=65536)
    a = ap.parse_args()
    make = {"roughness": with_layer, "anisotropy": brushed, "metal": textured_metal,
            "metallic": metallic_map, "mask": masked}[a.kind]
    variants = {"constant": make(None), "map": make("map")}
    if a.kind == "mask":
        variants["distinct"] = make("distinct")
    scene = BUILTIN["cornell_box"](resolution=tuple(a.resolution))
    builds = {name: [] for name in variants}
    for _ in range(a.rounds):
        for name, edit in variants.items():
            edited = edit(scene)
            t0 = time.perf_counter()
            RenderContext(edited)
            builds[name].append(time.perf_counter() - t0)
    print(f"render context build, median of {a.rounds}: " +
          ", ".join(f"{name} {np.median(t):.2f} s" for name, t in builds.items()))
    runs = {name: photon_pass("core", "cornell_box", tuple(a.resolution), a.paths, False, edit)
            for name, edit in variants.items()}
    rates = interleaved_rates(runs, a.rounds)
    for name in list(variants)[1:]:
        ratio = np.array(rates[name]) / np.array(rates["constant"])
        print(f"photon pass, {a.rounds} rounds of {a.paths} paths: constant {a.kind} "
              f"{np.median(rates['constant']):,.0f} vertices/s, {a.kind} {name} "
              f"{np.median(rates[name]):,.0f}: {np.median(ratio):.3f} of the constant "
              f"(range {ratio.min():.3f}-{ratio.max():.3f})")


if __name__ == "__main__":
    main()
