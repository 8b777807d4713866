"""core/voronoi.py: properties of the Voronoi Texture and values Cycles rendered (no bpy needed).

The values in CYCLES were read from Cycles' renders of tests/addon/test_voronoi_texture.py (Blender
5.0.1, float32 EXR) at three pixel centres of its 64 x 64 plane; Cycles computes in float32, hence
the 1e-5 tolerance (the measured differences are below 3e-6).
"""
from __future__ import annotations

import numpy as np
import pytest

from core import voronoi
from core.texture_hash import hash_int3_to_float3
from core.voronoi import voronoi_texture

POINTS = np.array([[-0.765625, 0.828125, 0.0], [0.296875, 0.046875, 0.0], [-0.609375, -0.828125, 0.0]])
# (case name, keyword arguments, output, Cycles' values at POINTS); scale 5, W = x.
CYCLES = [
    ("f1", {}, "Distance", [0.42120561, 0.72184247, 0.36125359]),
    ("f1", {}, "Color", [[0.14136775, 0.32004112, 0.37985957], [0.29644766, 0.57765937, 0.23337618],
                         [0.68497658, 0.81325346, 0.23764066]]),
    ("f1", {}, "Position", [[-0.77172649, 0.86400825, 0.07597192], [0.25928953, -0.08446813, 0.04667524],
                            [-0.6630047, -0.83734936, 0.04752813]]),
    ("f1_randomness_0.6", {"randomness": 0.6}, "Position",
     [[-0.78303587, 0.83840495, 0.04558315], [0.29842567, 0.00332482, 0.09543024],
      [-0.55018944, -0.79061741, 0.02643352]]),
    ("f2", {"feature": "F2"}, "Distance", [0.51287258, 0.8876515, 0.55660743]),
    ("smooth_f1", {"feature": "SMOOTH_F1"}, "Distance", [0.28213257, 0.59246761, 0.30897558]),
    ("smooth_f1", {"feature": "SMOOTH_F1"}, "Color",
     [[0.32307273, 0.29510251, 0.40648472], [0.39701498, 0.39501935, 0.26766014],
      [0.55938107, 0.5923456, 0.22801726]]),
    ("edge", {"feature": "DISTANCE_TO_EDGE"}, "Distance", [0.05128048, 0.09525364, 0.11540122]),
    ("n_sphere", {"feature": "N_SPHERE_RADIUS"}, "Radius", [0.25137377, 0.34394276, 0.33876693]),
    ("detail_2.5", {"detail": 2.5, "roughness": 0.6}, "Distance", [1.01653588, 1.53359485, 0.96393692]),
    ("detail_2.5", {"detail": 2.5, "roughness": 0.6}, "Position",
     [[-0.77732909, 0.82835388, 0.01511515], [0.28954816, 0.00351374, 0.04417501],
      [-0.63067019, -0.84285605, -0.00183952]]),
    ("2d", {"dimensions": "2D"}, "Color",
     [[0.14136775, 0.32004112, 0.37985957], [0.82021403, 0.02770685, 0.79525197],
      [0.41508821, 0.07818884, 0.22027934]]),
    ("4d", {"dimensions": "4D"}, "Distance", [0.68064415, 0.67969555, 0.4057543]),
    ("1d", {"dimensions": "1D"}, "Distance", [0.12117285, 0.33601451, 0.07987452]),
]
METRICS = ["EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI"]


def random_points(n=2000, seed=0, spread=3.0):
    return np.random.default_rng(seed).uniform(-spread, spread, (n, 3))


@pytest.mark.parametrize("name, kwargs, output, expected", CYCLES, ids=[f"{c[0]}-{c[2]}" for c in CYCLES])
def test_values_rendered_by_cycles(name, kwargs, output, expected):
    out = voronoi_texture(POINTS, 5.0, w=POINTS[:, 0], **kwargs)
    np.testing.assert_allclose(out[output], expected, rtol=0, atol=1e-5)


def test_shapes_dtypes_and_unproduced_outputs_are_zero():
    p = random_points(50)
    out = voronoi_texture(p, 5.0)
    assert {k: (v.shape, v.dtype) for k, v in out.items()} == {
        "Distance": ((50,), np.float64), "Color": ((50, 3), np.float64),
        "Position": ((50, 3), np.float64), "W": ((50,), np.float64), "Radius": ((50,), np.float64)}
    assert not out["W"].any() and not out["Radius"].any()
    edge = voronoi_texture(p, 5.0, feature="DISTANCE_TO_EDGE")
    assert edge["Distance"].all()
    assert not (edge["Color"].any() or edge["Position"].any() or edge["Radius"].any())
    radius = voronoi_texture(p, 5.0, feature="N_SPHERE_RADIUS")
    assert radius["Radius"].all() and not (radius["Distance"].any() or radius["Color"].any())
    assert all(v.shape[0] == 0 for v in voronoi_texture(np.zeros((0, 3)), 5.0).values())


def test_unknown_setting_raises():
    with pytest.raises(ValueError):
        voronoi_texture(np.zeros((1, 3)), 5.0, feature="F3")


@pytest.mark.parametrize("kwargs", [{}, {"feature": "SMOOTH_F1", "dimensions": "2D"},
                                    {"feature": "N_SPHERE_RADIUS"}, {"detail": 1.5, "feature": "F2"}])
def test_deterministic_and_independent_of_chunking(monkeypatch, kwargs):
    p = random_points(300)
    whole = voronoi_texture(p, 4.0, **kwargs)
    assert all(np.array_equal(whole[k], v) for k, v in voronoi_texture(p, 4.0, **kwargs).items())
    monkeypatch.setattr(voronoi, "CHUNK", 7)        # other chunks: other distinct cells, same result
    chunked = voronoi_texture(p, 4.0, **kwargs)
    assert all(np.array_equal(whole[k], v) for k, v in chunked.items())


@pytest.mark.parametrize("metric", METRICS)
@pytest.mark.parametrize("dimensions", ["1D", "2D", "3D", "4D"])
def test_f1_not_above_f2_not_above_smooth(metric, dimensions):
    p = random_points()
    kw = {"metric": metric, "exponent": 1.5, "dimensions": dimensions, "w": p[:, 0] * 0.7}
    f1 = voronoi_texture(p, 5.0, **kw)["Distance"]
    f2 = voronoi_texture(p, 5.0, feature="F2", **kw)["Distance"]
    smooth = voronoi_texture(p, 5.0, feature="SMOOTH_F1", **kw)["Distance"]
    assert np.all(f1 <= f2) and np.mean(f1 < f2) > 0.99
    assert np.all(smooth <= f1 + 1e-12)             # the smooth minimum lies below the minimum


@pytest.mark.parametrize("randomness", [1.0, 0.6])
def test_distance_is_zero_at_the_returned_position(randomness):
    p = random_points()
    first = voronoi_texture(p, 5.0, randomness=randomness)
    at_point = voronoi_texture(first["Position"], 5.0, randomness=randomness)
    np.testing.assert_allclose(at_point["Distance"], 0.0, atol=1e-12)
    np.testing.assert_allclose(at_point["Position"], first["Position"], atol=1e-12)
    np.testing.assert_array_equal(at_point["Color"], first["Color"])
    dist = np.linalg.norm(p - first["Position"], axis=1) * 5.0
    np.testing.assert_allclose(first["Distance"], dist, rtol=1e-12)


def test_randomness_zero_gives_the_integer_lattice():
    """pointPosition = cellOffset + hash * randomness: with randomness 0 every feature point is the
    (integer) corner of its cell, so F1 finds the nearest lattice point."""
    p = random_points()
    out = voronoi_texture(p, 5.0, randomness=0.0)
    nearest = np.round(p * 5.0)
    np.testing.assert_allclose(out["Position"] * 5.0, nearest, atol=1e-12)
    np.testing.assert_allclose(out["Distance"], np.linalg.norm(p * 5.0 - nearest, axis=1), atol=1e-12)
    # Distance to Edge: the faces of the cube around the lattice point, |x - round(x)| from 1/2.
    edge = voronoi_texture(p, 5.0, randomness=0.0, feature="DISTANCE_TO_EDGE")["Distance"]
    np.testing.assert_allclose(edge, 0.5 - np.abs(p * 5.0 - nearest).max(axis=1), atol=1e-12)
    radius = voronoi_texture(p, 5.0, randomness=0.0, feature="N_SPHERE_RADIUS")["Radius"]
    np.testing.assert_allclose(radius, 0.5)


def test_color_is_the_hash_of_the_feature_points_cell_and_constant_in_a_voronoi_cell():
    p = random_points(4000)
    out = voronoi_texture(p, 5.0)
    cell = np.floor(out["Position"] * 5.0).astype(np.int32)
    inside = np.all(out["Position"] * 5.0 - cell < 1.0, axis=1)     # hash < 1: the point's own cell
    np.testing.assert_array_equal(out["Color"][inside], hash_int3_to_float3(cell[inside]))
    # Points sharing a feature point share its colour.
    _, first, inverse = np.unique(out["Position"], axis=0, return_index=True, return_inverse=True)
    np.testing.assert_array_equal(out["Color"], out["Color"][first][inverse.reshape(-1)])
    assert len(first) > 100


def test_settings_clamped_as_in_cycles():
    p = random_points(200)
    same = [({"randomness": 1.7}, {"randomness": 1.0}),
            ({"feature": "SMOOTH_F1", "smoothness": 3.0}, {"feature": "SMOOTH_F1", "smoothness": 1.0}),
            ({"feature": "SMOOTH_F1", "smoothness": 0.0}, {}),
            ({"detail": 3.0, "roughness": 0.0}, {}),
            ({"detail": -2.0}, {}),
            ({"detail": 2.0, "roughness": 1.4}, {"detail": 2.0, "roughness": 1.0})]
    for a, b in same:
        out_a, out_b = voronoi_texture(p, 5.0, **a), voronoi_texture(p, 5.0, **b)
        assert all(np.array_equal(out_a[k], out_b[k]) for k in out_a), (a, b)


def test_normalize_divides_by_max_distance():
    p = random_points()
    for metric, max_distance in [("EUCLIDEAN", np.sqrt(3) * 0.8), ("MANHATTAN", 3 * 0.8), ("CHEBYCHEV", 0.8)]:
        plain = voronoi_texture(p, 5.0, randomness=0.6, metric=metric)
        normal = voronoi_texture(p, 5.0, randomness=0.6, metric=metric, normalize=True)
        np.testing.assert_allclose(normal["Distance"], plain["Distance"] / max_distance, rtol=1e-6)
        np.testing.assert_array_equal(normal["Color"], plain["Color"])
    octaves = voronoi_texture(p, 5.0, detail=2.0, roughness=0.5, normalize=True)
    assert 0.0 <= octaves["Color"].min() and octaves["Color"].max() <= 1.0    # sum of amplitudes 1.75


def test_octaves_mix_positions_and_sum_distances():
    p = random_points(500)
    one = voronoi_texture(p, 5.0)
    two = voronoi_texture(p, 5.0, detail=1.0, roughness=0.5, lacunarity=2.0)
    fine = voronoi_texture(p, 10.0)
    np.testing.assert_allclose(two["Distance"], one["Distance"] + 0.5 * fine["Distance"], rtol=1e-12)
    np.testing.assert_allclose(two["Color"], one["Color"] + 0.5 * fine["Color"], rtol=1e-12)
    np.testing.assert_allclose(two["Position"], 0.5 * one["Position"] + 0.5 * fine["Position"], atol=1e-12)


def test_unique_columns_are_numpys_whatever_the_cells():
    """``voronoi.unique_columns`` (packed int64 keys: the Voronoi's and the Gabor Texture's distinct
    cells, the 3D Gabor 1.85 times faster, ``benchmarks/texture_ab.py``) gives ``np.unique(axis=1)``'s
    columns in its order and the same inverse, for 1 to 4 dimensions, negative cells, spans too wide
    to pack (its own fallback) and cells that are not finite."""
    rng = np.random.default_rng(4)
    for dim in (1, 2, 3, 4):
        for spread in (3, 1000, 2 ** 40):
            cells = rng.integers(-spread, spread, size=(dim, 5000)).astype(np.float64)
            cells[:, 2500:] = cells[:, :2500]                      # (repeats)
            got, inverse = voronoi.unique_columns(cells)
            want, want_inverse = np.unique(cells, axis=1, return_inverse=True)
            np.testing.assert_array_equal(got, want)
            np.testing.assert_array_equal(inverse, want_inverse.reshape(-1))
            np.testing.assert_array_equal(got[:, inverse], cells)
    odd = np.array([[0.0, np.nan, 0.0, np.inf], [1.0, 2.0, 1.0, 3.0]])
    got, inverse = voronoi.unique_columns(odd)
    assert got.shape[1] == 3 and inverse[0] == inverse[2]
    assert voronoi.unique_columns(np.zeros((3, 0)))[0].shape == (3, 0)
