"""core.pattern_textures (Wave, Brick, Magic, White Noise, Gabor) against Cycles' own nodes (Blender 5.0).

Each case renders, with Cycles, a plane seen from above whose colour is one output of the node under
test, fed by Texture Coordinate (Object) -> optional axis permutation (Separate / Combine XYZ, so that
the plane's x, y can drive any axis) -> + SHIFT (so z is not 0); one sample per pixel at the pixel
centre (``blender_scenes.cycles_texture_values``).  Each pixel is compared with our function at the
same coordinates, formed from the pixel centre's world position in float32 as Cycles forms them (the
plane is neither moved nor turned, so Object coordinates are world positions).  Fac / Value show as
grey; Cycles does not clamp the emission colour.

Bounds: 99 % of the pixels must agree within 1e-3 (TOL, FRACTION) and the 99th percentile of the
difference must stay below 2e-4 (P99_TOL).  Measured (64 x 64 pixels; each case prints its numbers
with -s): no pixel of any case differs by 1e-3; the 99th percentile is <= 6e-5 and the maximum
<= 1.3e-4 (magic, depth 4 and distortion 2.5, where float32 sines of arguments amplified by the
distortion dominate; the wave <= 7.5e-6, the brick <= 7e-5).  Larger differences can only come from
discontinuities that float32 and float64 place a rounding apart: the saw / triangle wrap of the wave,
the brick / row a point falls in and the hard mortar edge, which is why not all pixels are held to
1e-3; a wrong formula, hash or setting differs at most pixels.

White noise hashes the float32 bits of its input, and Cycles' shading point may differ from the exact
pixel centre by an ulp, so its input is first snapped (Vector Math Snap, increment 1/32: one cell per
pixel, every pixel centre at least 0.06 cell from a cell edge): the keys are then exact and every
pixel must agree to 1e-6 (measured: exactly).
"""
from __future__ import annotations

import numpy as np
import pytest

import blender_scenes as bs
from core.pattern_textures import (brick_texture, gabor_texture, magic_texture, wave_texture,
                                   white_noise_texture)

RES = (64, 64)
SHIFT = (0.31, -0.17, 0.43)
TOL = 1e-3
FRACTION = 0.99
P99_TOL = 2e-4
SNAP = 1.0 / 32.0            # one snapping cell per pixel

# case: (node type, node properties, socket inputs, axis permutation); the shift is SHIFT unless in SHIFTS
WAVE = "ShaderNodeTexWave"
BRICK = "ShaderNodeTexBrick"
MAGIC = "ShaderNodeTexMagic"
COLORS = {"Color1": (0.9, 0.3, 0.1), "Color2": (0.1, 0.5, 0.8), "Mortar": (0.2, 0.25, 0.15)}
DISTORT = {"Distortion": 3.0, "Detail": 2.5, "Detail Scale": 1.3, "Detail Roughness": 0.6}
CASES = {
    "wave_bands_x_sin": (WAVE, {}, {"Scale": 1.5}, (0, 1, 2)),
    "wave_bands_y_saw_phase": (WAVE, {"bands_direction": "Y", "wave_profile": "SAW"},
                               {"Scale": 1.5, "Phase Offset": 0.7}, (0, 1, 2)),
    "wave_bands_z_tri": (WAVE, {"bands_direction": "Z", "wave_profile": "TRI"}, {"Scale": 1.5}, (0, 2, 1)),
    "wave_bands_diagonal_sin_distorted": (WAVE, {"bands_direction": "DIAGONAL"},
                                          {"Scale": 1.5, **DISTORT}, (0, 1, 2)),
    "wave_bands_x_tri_distorted_detail0": (WAVE, {"wave_profile": "TRI"},
                                           {"Scale": 1.5, "Distortion": 2.0, "Detail": 0.0}, (0, 1, 2)),
    "wave_rings_x_sin": (WAVE, {"wave_type": "RINGS", "rings_direction": "X"}, {"Scale": 1.5}, (2, 0, 1)),
    "wave_rings_y_saw": (WAVE, {"wave_type": "RINGS", "rings_direction": "Y", "wave_profile": "SAW"},
                         {"Scale": 1.5}, (0, 2, 1)),
    "wave_rings_z_tri": (WAVE, {"wave_type": "RINGS", "rings_direction": "Z", "wave_profile": "TRI"},
                         {"Scale": 1.5}, (0, 1, 2)),
    "wave_rings_spherical_saw_distorted": (WAVE, {"wave_type": "RINGS", "rings_direction": "SPHERICAL",
                                                  "wave_profile": "SAW"},
                                           {"Scale": 1.5, **DISTORT, "Detail": 3.0}, (0, 1, 2)),
    "wave_rings_z_sin_distorted_phase": (WAVE, {"wave_type": "RINGS", "rings_direction": "Z"},
                                         {"Scale": 2.5, **DISTORT, "Phase Offset": -1.3}, (0, 1, 2)),
    "brick_hard_mortar": (BRICK, {}, {**COLORS, "Scale": 1.5, "Mortar Size": 0.04, "Mortar Smooth": 0.0},
                          (0, 1, 2)),
    "brick_blender_defaults": (BRICK, {}, {"Scale": 1.5, "Mortar Smooth": 0.1}, (0, 1, 2)),
    "brick_offset_squash_bias": (BRICK, {"offset": 0.3, "offset_frequency": 3, "squash": 0.6,
                                         "squash_frequency": 2},
                                 {**COLORS, "Scale": 1.5, "Mortar Size": 0.04, "Mortar Smooth": 0.0,
                                  "Bias": 0.2}, (0, 1, 2)),
    "brick_smooth_negative_bias": (BRICK, {"offset_frequency": 1},
                                   {**COLORS, "Scale": 1.5, "Mortar Size": 0.08, "Mortar Smooth": 0.4,
                                    "Bias": -0.2}, (0, 1, 2)),
    "brick_sizes_full_smooth": (BRICK, {"offset": 0.7, "squash": 1.7, "squash_frequency": 3},
                                {**COLORS, "Scale": 2.0, "Mortar Size": 0.06, "Mortar Smooth": 1.0,
                                 "Brick Width": 0.7, "Row Height": 0.33, "Bias": 0.6}, (0, 1, 2)),
    "magic_depth0": (MAGIC, {"turbulence_depth": 0}, {}, (0, 1, 2)),
    "magic_depth1": (MAGIC, {"turbulence_depth": 1}, {}, (0, 1, 2)),
    "magic_depth2": (MAGIC, {"turbulence_depth": 2}, {}, (0, 1, 2)),
    "magic_depth3": (MAGIC, {"turbulence_depth": 3}, {}, (0, 1, 2)),
    "magic_depth4": (MAGIC, {"turbulence_depth": 4}, {}, (0, 1, 2)),
    "magic_depth4_distortion2.5": (MAGIC, {"turbulence_depth": 4}, {"Distortion": 2.5, "Scale": 3.0},
                                   (0, 1, 2)),
    "magic_depth10_distortion0.7": (MAGIC, {"turbulence_depth": 10}, {"Distortion": 0.7}, (0, 1, 2)),
    "magic_depth0_distortion0": (MAGIC, {"turbulence_depth": 0}, {"Distortion": 0.0}, (0, 1, 2)),
}
# Cases whose coordinates cross multiples of 2 pi (the magic texture's fmodf).
SHIFTS = {"magic_depth3": (6.0, -6.5, 0.43)}
# Cases rendered a second time for their float output (Fac) besides Color.
FAC_CASES = ["wave_rings_spherical_saw_distorted", "brick_smooth_negative_bias", "brick_hard_mortar",
             "magic_depth4_distortion2.5"]

PROPERTY_KEYWORDS = {"wave_type": "wave_type", "bands_direction": "bands_direction",
                     "rings_direction": "rings_direction", "wave_profile": "wave_profile",
                     "offset": "offset", "offset_frequency": "offset_frequency", "squash": "squash",
                     "squash_frequency": "squash_frequency", "turbulence_depth": "depth"}
INPUT_KEYWORDS = {"Scale": "scale", "Distortion": "distortion", "Detail": "detail",
                  "Detail Scale": "detail_scale", "Detail Roughness": "detail_roughness",
                  "Phase Offset": "phase_offset", "Color1": "color1", "Color2": "color2", "Mortar": "mortar",
                  "Mortar Size": "mortar_size", "Mortar Smooth": "mortar_smooth", "Bias": "bias",
                  "Brick Width": "brick_width", "Row Height": "row_height"}
FUNCTIONS = {WAVE: wave_texture, BRICK: brick_texture, MAGIC: magic_texture}


def _coordinates(nt, perm, shift):
    """Object coordinates, axes permuted (output axis k reads input axis perm[k]), plus shift."""
    coords = nt.nodes.new("ShaderNodeTexCoord")
    vector = coords.outputs["Object"]
    if tuple(perm) != (0, 1, 2):
        sep = nt.nodes.new("ShaderNodeSeparateXYZ")
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(vector, sep.inputs[0])
        for k, source in enumerate(perm):
            nt.links.new(sep.outputs[source], comb.inputs[k])
        vector = comb.outputs[0]
    add = nt.nodes.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    add.inputs[1].default_value = shift
    nt.links.new(vector, add.inputs[0])
    return add.outputs["Vector"]


def _our_coordinates(positions, perm, shift):
    """(n, 3) float64: the float32 coordinates Cycles forms for :func:`_coordinates`."""
    p = positions.reshape(-1, 3).astype(np.float32)[:, list(perm)]
    return (p + np.asarray(shift, np.float32)).astype(np.float64)


def _render(connect, tmp_path, name):
    mat, positions = bs.texture_plane(connect, resolution=RES)
    return bs.cycles_texture_values(mat, tmp_path / f"{name}.exr").reshape(-1, 3), positions


def _check(case, diff):
    """Print the case's differences (n,) and assert the bounds of the module docstring."""
    far, p99 = np.mean(diff > TOL), np.percentile(diff, 99)
    print(f"{case}: max {diff.max():.2e} p99 {p99:.2e} > {TOL:g}: {100 * far:.2f} %")
    assert far <= 1.0 - FRACTION, (case, far)
    assert p99 < P99_TOL, (case, p99)


def _case(case, output):
    node_type, props, inputs, perm = CASES[case]
    shift = SHIFTS.get(case, SHIFT)

    def connect(nt):
        node = nt.nodes.new(node_type)
        for key, value in props.items():
            setattr(node, key, value)
        for key, value in inputs.items():
            node.inputs[key].default_value = (*value, 1.0) if isinstance(value, tuple) else value
        nt.links.new(_coordinates(nt, perm, shift), node.inputs["Vector"])
        return node.outputs[output]

    kwargs = {PROPERTY_KEYWORDS[k]: v for k, v in props.items()}
    kwargs.update({INPUT_KEYWORDS[k]: v for k, v in inputs.items()})
    if node_type == BRICK:                       # Blender's defaults for the colours not set
        kwargs = {"color1": (0.8, 0.8, 0.8), "color2": (0.2, 0.2, 0.2), "mortar": (0.0, 0.0, 0.0), **kwargs}
    return connect, lambda positions: FUNCTIONS[node_type](_our_coordinates(positions, perm, shift), **kwargs)


@pytest.mark.parametrize("case", list(CASES))
def test_color_matches_cycles(addon, tmp_path, case):
    connect, ours = _case(case, "Color")
    cycles, positions = _render(connect, tmp_path, case)
    color = ours(positions)["Color"]
    assert np.ptp(cycles, axis=0).max() > 0.05          # a real pattern, not a constant
    _check(case, np.abs(color - cycles).max(axis=1))


@pytest.mark.parametrize("case", FAC_CASES)
def test_fac_matches_cycles(addon, tmp_path, case):
    connect, ours = _case(case, "Fac")
    cycles, positions = _render(connect, tmp_path, f"{case}_fac")
    fac = ours(positions)["Fac"]
    assert np.allclose(cycles[:, 0], cycles[:, 1]) and np.allclose(cycles[:, 0], cycles[:, 2])
    assert np.ptp(cycles[:, 0]) > 0.05
    _check(f"{case} fac", np.abs(fac - cycles[:, 0]))


# ---------------------------------------------------------------------------------- white noise
def _white_noise_connect(dimensions, output):
    def connect(nt):
        snap = nt.nodes.new("ShaderNodeVectorMath")
        snap.operation = "SNAP"
        snap.inputs[1].default_value = (SNAP, SNAP, SNAP)
        nt.links.new(_coordinates(nt, (0, 1, 2), SHIFT), snap.inputs[0])
        node = nt.nodes.new("ShaderNodeTexWhiteNoise")
        node.noise_dimensions = dimensions
        if dimensions == "1D":               # W = the snapped x (the Vector socket is hidden)
            sep = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(snap.outputs["Vector"], sep.inputs[0])
            nt.links.new(sep.outputs["X"], node.inputs["W"])
        else:
            nt.links.new(snap.outputs["Vector"], node.inputs["Vector"])
        if dimensions == "4D":
            node.inputs["W"].default_value = 0.37
        return node.outputs[output]

    return connect


def _snapped(positions):
    """(n, 3) float64: Cycles' float32 floor(v / b) * b of the shifted coordinates, and the smallest
    distance (in cells) of any v / b from a cell's edge."""
    v = _our_coordinates(positions, (0, 1, 2), SHIFT).astype(np.float32)
    b = np.float32(SNAP)
    cells = v / b
    margin = np.abs(cells - np.round(cells)).min()
    return (np.floor(cells) * b).astype(np.float64), margin


@pytest.mark.parametrize("dimensions, output", [("1D", "Color"), ("2D", "Color"), ("3D", "Color"),
                                                ("4D", "Color"), ("3D", "Value")])
def test_white_noise_matches_cycles_exactly(addon, tmp_path, dimensions, output):
    cycles, positions = _render(_white_noise_connect(dimensions, output), tmp_path, f"white_{dimensions}")
    vector, margin = _snapped(positions)
    assert margin > 0.05                           # no pixel centre near a snapping edge
    ours = white_noise_texture(vector, dimensions=dimensions, w=vector[:, 0] if dimensions == "1D" else 0.37)
    expected = ours[output] if output == "Color" else np.repeat(ours["Value"][:, None], 3, axis=1)
    assert np.ptp(cycles) > 0.5
    diff = np.abs(expected - cycles).max(axis=1)
    print(f"white {dimensions} {output}: max {diff.max():.2e}")
    assert diff.max() < 1e-6


# ---------------------------------------------------------------------------------- gabor
GABOR = {   # case: (gabor_type, socket inputs)
    "2d_anisotropic": ("2D", {"Scale": 3.0, "Frequency": 2.5}),
    "2d_isotropic_turned": ("2D", {"Scale": 4.0, "Frequency": 1.5, "Anisotropy": 0.3, "Orientation 2D": 1.1}),
    "3d_default": ("3D", {}),
    "3d_turned": ("3D", {"Scale": 3.0, "Frequency": 3.0, "Anisotropy": 0.6,
                         "Orientation 3D": (0.2, -0.5, 0.8)}),
}


@pytest.mark.parametrize("output", ["Value", "Phase", "Intensity"])
@pytest.mark.parametrize("case", list(GABOR))
def test_gabor_matches_cycles(addon, tmp_path, case, output):
    """The Gabor Texture (stop 42; before, unsupported: the socket's value), 2D and 3D, anisotropic
    and turned towards isotropic, each output.  The Phase wraps from 1 to 0 where the phasor
    crosses the negative real axis: pixels a rounding from there may differ by a whole turn."""
    gabor_type, inputs = GABOR[case]

    def connect(nt):
        node = nt.nodes.new("ShaderNodeTexGabor")
        node.gabor_type = gabor_type
        for key, value in inputs.items():
            sock = next(s for s in node.inputs if s.identifier == key or s.name == key)
            sock.default_value = value
        nt.links.new(_coordinates(nt, (0, 1, 2), SHIFT), node.inputs["Vector"])
        return node.outputs[output]

    cycles, positions = _render(connect, tmp_path, f"gabor_{case}_{output}")
    keywords = {"Scale": "scale", "Frequency": "frequency", "Anisotropy": "anisotropy",
                "Orientation 2D": "orientation_2d", "Orientation 3D": "orientation_3d"}
    ours = gabor_texture(_our_coordinates(positions, (0, 1, 2), SHIFT), gabor_type=gabor_type,
                         **{keywords[k]: v for k, v in inputs.items()})[output]
    assert np.ptp(cycles[:, 0]) > 0.05
    diff = np.abs(ours - cycles[:, 0])
    if output == "Phase":
        diff = np.minimum(diff, 1.0 - diff)          # (a whole turn apart is the same phase)
    _check(f"gabor {case} {output}", diff)
