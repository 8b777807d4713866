"""core.noise.noise_texture against Cycles' own Noise Texture node (Blender 5.0).

A plane seen from above is textured by Texture Coordinate (Object) + a constant shift -> Noise Texture,
rendered by Cycles with one sample and a 0.01 pixel filter (blender_scenes.cycles_texture_values), and
each pixel compared with ``noise_texture`` at the pixel centre's world position plus the same shift
(the plane is neither moved nor turned, so Object coordinates are world positions; the shift makes z
nonzero, so the 3D noise is not sampled on a lattice plane).

Bounds: Cycles evaluates in float32, we in float64.  The 99th percentile of |difference| is held below
1e-3 and the maximum below 2e-3 (measured: p99 1e-5 .. 1e-4, max <= 2e-4).  The differences come from
float32 rounding of the coordinates: p + offset (offsets 100..200) times lacunarity**octave reaches
~2000, where one float32 ulp is ~1e-4 of a cell, and the float32 shading point differs from the exact
pixel centre by a few ulps; the noise's slope (a few per cell, more for the unnormalised and
multiplicative types whose values exceed [0, 1]) scales them.  Near lattice-cell boundaries the two
precisions can pick neighbouring cells, but the noise is continuous there, so this adds nothing larger:
hence a maximum only ~10x the typical difference, while a wrong hash, gradient, offset or fractal step
gives differences of order 0.1 at most pixels.
"""
from __future__ import annotations

import numpy as np
import pytest

import blender_scenes as bs

SHIFT = (0.31, -0.17, 0.43)
BASE = dict(scale=5.0, detail=2.5, roughness=0.6, lacunarity=2.3, distortion=0.0)

CASES = {
    "fbm": dict(),
    "fbm_raw": dict(normalize=False),
    "fbm_distorted": dict(distortion=0.7),
    "fbm_detail3": dict(detail=3.0),
    "multifractal": dict(noise_type="MULTIFRACTAL"),
    "hybrid": dict(noise_type="HYBRID_MULTIFRACTAL", offset=0.8, gain=1.5),
    "hybrid_cutoff": dict(noise_type="HYBRID_MULTIFRACTAL", detail=4.5),   # weights often fall below 0.001
    "ridged": dict(noise_type="RIDGED_MULTIFRACTAL", offset=1.0, gain=2.0),
    "hetero": dict(noise_type="HETERO_TERRAIN", offset=0.5, distortion=0.7),
    "fbm_2d": dict(dimensions="2D", distortion=0.7),
    "fbm_4d": dict(dimensions="4D", w=0.37, distortion=0.7),
    "fbm_1d": dict(dimensions="1D", distortion=0.7),      # W fed by the shifted x coordinate
}


def _settings(case):
    kw = {**BASE, **CASES[case]}
    opts = {k: kw.pop(k) for k in ("noise_type", "normalize", "dimensions") if k in kw}
    return kw, opts


def shifted_object_coordinates(nt, shift):
    """Output socket of Object coordinates plus ``shift`` (a Vector Math Add)."""
    coords = nt.nodes.new("ShaderNodeTexCoord")
    add = nt.nodes.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    add.inputs[1].default_value = shift
    nt.links.new(coords.outputs["Object"], add.inputs[0])
    return add.outputs["Vector"]


def _connect(case, output):
    """Node graph builder for texture_plane: returns the Noise Texture's ``output`` socket."""
    kw, opts = _settings(case)

    def connect(nt):
        shifted = shifted_object_coordinates(nt, SHIFT)
        noise = nt.nodes.new("ShaderNodeTexNoise")
        noise.noise_type = opts.get("noise_type", "FBM")
        noise.normalize = opts.get("normalize", True)
        noise.noise_dimensions = opts.get("dimensions", "3D")
        names = {"scale": "Scale", "detail": "Detail", "roughness": "Roughness", "lacunarity": "Lacunarity",
                 "distortion": "Distortion", "offset": "Offset", "gain": "Gain", "w": "W"}
        for key, value in kw.items():
            noise.inputs[names[key]].default_value = value
        if opts.get("dimensions") == "1D":         # no Vector socket: W = x
            xyz = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(shifted, xyz.inputs[0])
            nt.links.new(xyz.outputs["X"], noise.inputs["W"])
        else:
            nt.links.new(shifted, noise.inputs["Vector"])
        return noise.outputs[0] if output == "fac" else noise.outputs["Color"]

    return connect


def _ours(case, positions):
    from amcmcppm.core.noise import noise_texture

    kw, opts = _settings(case)
    kw.update(opts)
    vector = positions.reshape(-1, 3) + SHIFT
    if opts.get("dimensions") == "1D":
        kw["w"] = vector[:, 0]
    return noise_texture(vector, **kw)


def _render(case, output, tmp_path):
    mat, positions = bs.texture_plane(_connect(case, output), resolution=(48, 48))
    pixels = bs.cycles_texture_values(mat, tmp_path / f"{case}_{output}.exr")
    return pixels.reshape(-1, 3), positions


def _check(case, diff):
    p99, worst = np.percentile(diff, 99), diff.max()
    print(f"{case}: p99 {p99:.2e} max {worst:.2e}")
    assert p99 < 1e-3, (case, p99, worst)
    assert worst < 2e-3, (case, p99, worst)


@pytest.mark.parametrize("case", list(CASES))
def test_color_matches_cycles(addon, tmp_path, case):
    cycles, positions = _render(case, "color", tmp_path)
    fac, color = _ours(case, positions)
    assert np.ptp(cycles[:, 1]) > 0.05            # a real texture, not a constant
    _check(case, np.abs(color - cycles))


@pytest.mark.parametrize("case", ["fbm_distorted", "ridged"])
def test_fac_matches_cycles(addon, tmp_path, case):
    cycles, positions = _render(case, "fac", tmp_path)
    fac, _ = _ours(case, positions)
    assert np.allclose(cycles[:, 0], cycles[:, 1]) and np.allclose(cycles[:, 0], cycles[:, 2])
    _check(case, np.abs(fac - cycles[:, 0]))


def test_large_coordinates_fac_matches_cycles(addon, tmp_path):
    """Coordinates beyond 1e6: Cycles' fmod(p, 100000) and half-cell precision correction.

    Scale 1 and lacunarity 2 keep every product exact in float32, so feeding ``noise_texture`` the
    float32 sums Cycles forms (step 0.125 at 1e6..2e6) reproduces its lattice coordinates exactly.
    40 pixels over 2 units keep every pixel centre 0.0125 away from a float32 rounding tie."""
    big = np.array([1.2e6, -1.6e6, 1.1e6])

    def connect(nt):
        shifted = shifted_object_coordinates(nt, big)
        noise = nt.nodes.new("ShaderNodeTexNoise")
        for name, value in (("Scale", 1.0), ("Detail", 2.0), ("Roughness", 0.5), ("Lacunarity", 2.0)):
            noise.inputs[name].default_value = value
        nt.links.new(shifted, noise.inputs["Vector"])
        return noise.outputs[0]

    from amcmcppm.core.noise import noise_texture

    mat, positions = bs.texture_plane(connect, resolution=(40, 40))
    cycles = bs.cycles_texture_values(mat, tmp_path / "large.exr").reshape(-1, 3)[:, 0]
    vector = (positions.reshape(-1, 3).astype(np.float32) + big.astype(np.float32)).astype(np.float64)
    fac, _ = noise_texture(vector, 1.0, 2.0, 0.5, 2.0, 0.0)
    assert np.ptp(cycles) > 0.05
    _check("large", np.abs(fac - cycles))
