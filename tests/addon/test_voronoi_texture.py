"""The Voronoi Texture of ``core/voronoi.py`` against Cycles' own evaluation of the node (bpy 5.0).

Each case renders, with Cycles, a plane whose colour is one output of a Voronoi Texture node fed by
the Texture Coordinate node's Object output plus a constant SHIFT (so that z is not 0 and all cells
around the plane are used; W, for 1D and 4D, is the shifted x), one sample per pixel at the pixel
centre (``blender_scenes.cycles_texture_values``), and compares it with ``voronoi_texture`` at the
pixel centres' world positions plus SHIFT (the plane is neither moved nor turned).  Distance comes
as grey (d, d, d); Color, Position and W as they are (Cycles does not clamp the emission colour:
negative positions survive).

Bounds: Cycles computes in float32, ``core/voronoi.py`` in float64; measured (64 x 64 pixels) the
worst pixel differs by < 7e-6 (99th percentile < 4e-6) in every case but Minkowski with exponent 0.5
(5e-5 here, 1.7e-4 without the shift: float32 ``powf`` of sums of square roots), and no pixel
differs by 1e-3.  The tests allow 1 % of the pixels to differ by more than 1e-3 in the outputs that
jump between cells (Color, Position, W, Radius): where two feature points are equally near within
float32 rounding, i.e. on the pattern's edges, the float32 and float64 searches may pick different
cells.  Distance is continuous across those edges, so it must agree at every pixel.
"""
from __future__ import annotations

import numpy as np
import pytest

import blender_scenes as bs
from core.voronoi import voronoi_texture

RES = (64, 64)
SHIFT = (0.31, -0.17, 0.43)
EDGE_TOL = 1e-3             # a pixel this far off took another cell than Cycles (float32 tie)
EDGE_FRACTION = 0.01        # ... allowed for at most 1 % of the pixels
P99_TOL = 1e-5              # float32 rounding
DISTANCE_TOL = 2e-5         # Distance is continuous: every pixel
POWF_TOL = 1e-3             # Minkowski with a small exponent (float32 powf), for P99 and Distance

# Node properties (set on the node) and inputs (default values of its sockets); "w_from_x" links W.
PROPERTIES = {"feature", "distance", "voronoi_dimensions", "normalize"}
CASES = {
    "f1": {},
    "f1_randomness_0.6": {"Randomness": 0.6},
    "f1_scale_13.7": {"Scale": 13.7, "Randomness": 0.85},
    "f2": {"feature": "F2"},
    "smooth_f1": {"feature": "SMOOTH_F1"},
    "smooth_f1_0.3": {"feature": "SMOOTH_F1", "Smoothness": 0.3, "Randomness": 0.6},
    "edge": {"feature": "DISTANCE_TO_EDGE"},
    "n_sphere": {"feature": "N_SPHERE_RADIUS"},
    "manhattan": {"distance": "MANHATTAN"},
    "chebychev_f2": {"distance": "CHEBYCHEV", "feature": "F2"},
    "minkowski_0.5": {"distance": "MINKOWSKI", "Exponent": 0.5},
    "minkowski_3_smooth": {"distance": "MINKOWSKI", "Exponent": 3.0, "feature": "SMOOTH_F1"},
    "detail_2.5": {"Detail": 2.5, "Roughness": 0.6},
    "detail_2.5_f2_normalize": {"Detail": 2.5, "Roughness": 0.6, "feature": "F2", "normalize": True},
    "detail_1.7_smooth_lacunarity": {"Detail": 1.7, "Roughness": 0.6, "Lacunarity": 2.7,
                                     "feature": "SMOOTH_F1", "normalize": True},
    "detail_2.5_edge_normalize": {"Detail": 2.5, "Roughness": 0.6, "feature": "DISTANCE_TO_EDGE",
                                  "normalize": True},
    "2d": {"voronoi_dimensions": "2D"},
    "2d_smooth": {"voronoi_dimensions": "2D", "feature": "SMOOTH_F1"},
    "2d_edge": {"voronoi_dimensions": "2D", "feature": "DISTANCE_TO_EDGE"},
    "2d_n_sphere": {"voronoi_dimensions": "2D", "feature": "N_SPHERE_RADIUS"},
    "4d": {"voronoi_dimensions": "4D", "w_from_x": True},
    "4d_f2_detail": {"voronoi_dimensions": "4D", "w_from_x": True, "feature": "F2", "Randomness": 0.6,
                     "Detail": 1.5},
    "4d_edge": {"voronoi_dimensions": "4D", "w_from_x": True, "feature": "DISTANCE_TO_EDGE"},
    "1d": {"voronoi_dimensions": "1D", "w_from_x": True},
    "1d_f2": {"voronoi_dimensions": "1D", "w_from_x": True, "feature": "F2"},
    "1d_smooth": {"voronoi_dimensions": "1D", "w_from_x": True, "feature": "SMOOTH_F1"},
    "1d_edge": {"voronoi_dimensions": "1D", "w_from_x": True, "feature": "DISTANCE_TO_EDGE"},
    "1d_n_sphere": {"voronoi_dimensions": "1D", "w_from_x": True, "feature": "N_SPHERE_RADIUS"},
}
# Our keyword for each node property / input.
KEYWORDS = {"Scale": "scale", "Detail": "detail", "Roughness": "roughness", "Lacunarity": "lacunarity",
            "Randomness": "randomness", "Exponent": "exponent", "Smoothness": "smoothness",
            "feature": "feature", "distance": "metric", "voronoi_dimensions": "dimensions",
            "normalize": "normalize"}


def outputs(case):
    """The node's outputs a case produces (the sockets its dimensions show)."""
    feature, dims = case.get("feature", "F1"), case.get("voronoi_dimensions", "3D")
    if feature == "DISTANCE_TO_EDGE":
        return ["Distance"]
    if feature == "N_SPHERE_RADIUS":
        return ["Radius"]
    return ["Distance", "Color"] + {"1D": ["W"], "2D": ["Position"], "3D": ["Position"],
                                    "4D": ["Position", "W"]}[dims]


PARAMS = [pytest.param(name, out, id=f"{name}-{out}") for name, case in CASES.items()
          for out in outputs(case)]


def node_graph(case, output):
    """``connect`` for ``texture_plane``: Object coordinates + SHIFT -> Voronoi Texture -> ``output``."""
    def connect(nt):
        coords = nt.nodes.new("ShaderNodeTexCoord")
        shifted = nt.nodes.new("ShaderNodeVectorMath")
        shifted.operation = "ADD"
        shifted.inputs[1].default_value = SHIFT
        nt.links.new(coords.outputs["Object"], shifted.inputs[0])
        node = nt.nodes.new("ShaderNodeTexVoronoi")
        for key, value in case.items():
            if key in PROPERTIES:
                setattr(node, key, value)
            elif key != "w_from_x":
                node.inputs[key].default_value = value
        node.inputs["Scale"].default_value = case.get("Scale", 5.0)
        if node.inputs.get("Vector") is not None:       # 1D has no Vector socket
            nt.links.new(shifted.outputs[0], node.inputs["Vector"])
        if case.get("w_from_x"):
            xyz = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(shifted.outputs[0], xyz.inputs[0])
            nt.links.new(xyz.outputs["X"], node.inputs["W"])
        return node.outputs[output]
    return connect


def ours(case, positions, output):
    """(H, W, 3) of :func:`voronoi_texture` at the (H, W, 3) positions, as Cycles shows ``output``."""
    kwargs = {KEYWORDS[k]: v for k, v in case.items() if k in KEYWORDS}
    kwargs.setdefault("scale", 5.0)
    p = positions.reshape(-1, 3) + np.float32(SHIFT)        # Cycles adds the float32 constant
    value = voronoi_texture(p, w=p[:, 0] if case.get("w_from_x") else 0.0, **kwargs)[output]
    value = value.reshape(*positions.shape[:2], -1)
    return np.broadcast_to(value, positions.shape)          # a float shows as grey


@pytest.mark.parametrize("name, output", PARAMS)
def test_voronoi_matches_cycles(addon, tmp_path, name, output):
    case = CASES[name]
    mat, positions = bs.texture_plane(node_graph(case, output), RES)
    cycles = bs.cycles_texture_values(mat, tmp_path / "voronoi.exr")
    diff = np.abs(ours(case, positions, output) - cycles).max(axis=-1)
    assert np.all(np.isfinite(cycles)) and cycles.std() > 1e-3      # a real pattern was rendered
    fine = POWF_TOL if case.get("distance") == "MINKOWSKI" else P99_TOL
    report = f"max {diff.max():.2e}, p99 {np.percentile(diff, 99):.2e}"
    assert np.percentile(diff, 99) < fine, report
    if output == "Distance":
        assert diff.max() < max(fine, DISTANCE_TOL), report
    else:
        assert np.mean(diff > EDGE_TOL) <= EDGE_FRACTION, report
