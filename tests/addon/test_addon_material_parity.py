"""Glossy, Principled and metal against Cycles (same bpy), and where we still differ.

A block of the material on a grey floor, lit by the world or by an area light, 64 x 64, 16
passes.  The centre of the image (mostly the block) and the whole image are compared as
linear EXR means with Cycles at 512 samples (settings of ``test_addon_parity.py``).

Measured once (ours / Cycles, centre; the whole image within 0.95-1.06 for these):
Glossy roughness 0.3 0.99 (world) and 1.06 (area; not explained yet);
Principled (roughness 0.5 and 0.2) 0.95 to 0.97; metal (Principled, metallic 1, roughness
0.3) 0.96 and 1.03.  Rough glossy and metal are too dark: Glossy roughness 0.6 0.83 and
0.82, metal roughness 0.8 0.73 and 0.74.  Our GGX is single-scattering; Cycles' default
(multiscatter GGX) keeps the energy that bounces between microfacets, which grows with
roughness.  Those cases are strict expected failures: when the energy is compensated they
pass, and the marks must go.
"""
from __future__ import annotations

import bpy
import pytest

import blender_scenes as bs
from test_addon_parity import OURS, RESOLUTION, use_cycles

pytestmark = pytest.mark.slow

TOLERANCE_CENTRE, TOLERANCE_WHOLE = 0.10, 0.08
MATERIALS = {
    "glossy_0.3": ("ShaderNodeBsdfGlossy", {"Color": (0.8, 0.8, 0.8, 1.0), "Roughness": 0.3}),
    "principled_0.5": ("ShaderNodeBsdfPrincipled", {"Base Color": (0.6, 0.3, 0.2, 1.0), "Roughness": 0.5}),
    "principled_0.2": ("ShaderNodeBsdfPrincipled", {"Base Color": (0.6, 0.3, 0.2, 1.0), "Roughness": 0.2}),
    "metal_0.3": ("ShaderNodeBsdfPrincipled", {"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.3,
                                               "Metallic": 1.0}),
    "glossy_0.6": ("ShaderNodeBsdfGlossy", {"Color": (0.8, 0.8, 0.8, 1.0), "Roughness": 0.6}),
    "metal_0.8": ("ShaderNodeBsdfPrincipled", {"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.8,
                                               "Metallic": 1.0}),
}
SINGLE_SCATTER_GGX = pytest.mark.xfail(strict=True, reason="single-scattering GGX loses the energy that "
                                       "Cycles' multiscatter GGX keeps (17-27 % at roughness 0.6-0.8)")


def build(material, light):
    node, inputs = MATERIALS[material]
    bs.empty_scene(RESOLUTION, **dict(OURS, passes=16))
    bs.plane("Floor", size=10.0, material=bs.diffuse("Floor", (0.5, 0.5, 0.5)))
    bs.cube("Block", size=1.5, material=bs._material(material, node, **inputs), location=(0, 0, 0.75),
            rotation=(0, 0, 0.6))
    bs.camera(location=(0, -5, 4), target=(0, 0, 0.5), lens=50.0)
    if light == "world":
        bs.world((0.4, 0.5, 0.6), strength=1.0)
    else:
        bs.light("AREA", location=(-1.5, -2.0, 3.0), target=(0, 0, 0), energy=300.0, shape="SQUARE", size=1.5)


CASES = [(m, light) for m in ("glossy_0.3", "principled_0.5", "principled_0.2", "metal_0.3")
         for light in ("world", "area")]
CASES += [pytest.param(m, light, marks=SINGLE_SCATTER_GGX) for m in ("glossy_0.6", "metal_0.8")
          for light in ("world", "area")]


@pytest.mark.parametrize("material, light", CASES)
def test_material_matches_cycles(addon, tmp_path, material, light):
    build(material, light)
    use_cycles(bpy.context.scene)
    cycles = bs.render_exr(tmp_path / "cycles.exr")
    build(material, light)
    ours = bs.render_exr(tmp_path / "ours.exr")
    centre = (slice(16, 48), slice(20, 44), slice(0, 3))
    c_ours, c_cycles = ours[centre].mean(), cycles[centre].mean()
    print(f"material {material} {light}: centre {c_ours / c_cycles:.3f}, "
          f"whole {ours[..., :3].mean() / cycles[..., :3].mean():.3f}")
    assert c_cycles > 0.05
    assert c_ours == pytest.approx(c_cycles, rel=TOLERANCE_CENTRE)
    assert ours[..., :3].mean() == pytest.approx(cycles[..., :3].mean(), rel=TOLERANCE_WHOLE)
