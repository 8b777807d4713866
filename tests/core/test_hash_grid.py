"""The measurement-point grid returns exactly the pairs a brute-force search finds."""
import numpy as np
import pytest

from core.hash_grid import GROUP_SPAN, HashGrid, brute_force_query


def random_points(rng, n, scale, offset, r_range):
    p = offset + scale * rng.random((n, 3))
    r = scale * rng.uniform(*r_range, size=n)
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return p, r, nrm


def pair_set(p, j):
    return set(zip(p.tolist(), j.tolist()))


def query_matches_brute_force(grid, x, xn, pts, radii, nrm, scale=1.0):
    """The grid's pairs for photons ``x`` equal brute force's, except pairs at the boundary
    (float32 distances relative to the cell: within 1e-5 of the radius).  Returns brute
    force's pairs."""
    p, j, _ = grid.query(x, xn)
    bp, bj = brute_force_query(x, xn, pts, radii, nrm)
    got, want = pair_set(p, j), pair_set(bp, bj)
    for pi, pj in got ^ want:
        d = np.linalg.norm(x[pi] - pts[pj])
        assert abs(d - radii[pj]) < 1e-5 * radii[pj] + 1e-6 * scale, (pi, pj, d, radii[pj])
    return want


@pytest.mark.parametrize("scale,offset", [(1.0, 0.0), (1e-3, 0.0), (10.0, 1e4), (1e3, -5e3)])
@pytest.mark.parametrize("r_range", [(0.01, 0.08), (0.001, 0.3)])
def test_grid_query_equals_brute_force(scale, offset, r_range):
    rng = np.random.default_rng(7)
    pts, radii, nrm = random_points(rng, 3000, scale, offset, r_range)
    grid = HashGrid(pts, radii, nrm)
    # Photons near the points (so many pairs exist) and elsewhere; normals from random points.
    x = np.concatenate([pts[rng.integers(0, 3000, 1500)] + scale * 0.03 * rng.normal(size=(1500, 3)),
                        offset + scale * (rng.random((500, 3)) * 1.4 - 0.2)])
    xn = nrm[rng.integers(0, 3000, 2000)]
    xn[:1000] = nrm[rng.integers(0, 3000, 1000)]
    want = query_matches_brute_force(grid, x, xn, pts, radii, nrm, scale)
    assert len(want) > 100


@pytest.mark.parametrize("scale,offset", [(1.0, 0.0), (10.0, 1e4)])
def test_grid_without_normals_tests_the_distance_alone(scale, offset):
    """Volume points' grid: spheres, no normal test; mixing the two kinds is an error."""
    rng = np.random.default_rng(9)
    pts, radii, nrm = random_points(rng, 2000, scale, offset, (0.01, 0.1))
    grid = HashGrid(pts, radii, None)
    assert not grid.has_normals and HashGrid(pts, radii, nrm).has_normals
    x = pts[rng.integers(0, 2000, 1500)] + scale * 0.03 * rng.normal(size=(1500, 3))
    want = query_matches_brute_force(grid, x, None, pts, radii, None, scale)
    with_normals = pair_set(*brute_force_query(x, nrm[rng.integers(0, 2000, 1500)], pts, radii, nrm))
    assert len(want) > 2 * len(with_normals) > 100     # the normal test would have dropped most
    with pytest.raises(ValueError, match="normals"):
        grid.query(x, nrm[:1500])
    with pytest.raises(ValueError, match="normals"):
        HashGrid(pts, radii, nrm).query(x, None)


def test_grid_returns_the_cosines_with_the_point_normals():
    rng = np.random.default_rng(8)
    pts, radii, nrm = random_points(rng, 500, 1.0, 0.0, (0.05, 0.2))
    grid = HashGrid(pts, radii, nrm)
    x = pts[rng.integers(0, 500, 300)]
    xn = nrm[rng.integers(0, 500, 300)]
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p, j, cos = grid.query(x, xn, d)
    assert len(p) > 0
    np.testing.assert_allclose(cos, np.einsum("ij,ij->i", d[p], nrm[j]), atol=1e-6)


def test_empty_grid_and_far_photons_return_no_pairs():
    grid = HashGrid(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    p, j, _ = grid.query(np.zeros((5, 3)), np.tile([0, 0, 1.0], (5, 1)))
    assert len(p) == 0 and len(j) == 0
    grid = HashGrid(np.zeros((1, 3)), np.ones(1), np.array([[0, 0, 1.0]]))
    p, _, _ = grid.query(np.array([[1e6, 0, 0], [0.5, 0, 0]]), np.tile([0, 0, 1.0], (2, 1)))
    assert p.tolist() == [1]


def test_tiny_radius_in_a_huge_scene_keeps_the_grid_bounded():
    # pbrt-v4 #141: cell counts overflow as r -> 0.  Here r = 1e-9 of a 1e4 scene.
    rng = np.random.default_rng(9)
    pts = rng.random((1000, 3)) * 1e4
    radii = np.full(1000, 1e-5)
    nrm = np.tile([0, 0, 1.0], (1000, 1))
    grid = HashGrid(pts, radii, nrm)
    assert (grid.dims < 2 ** 21).all()
    assert grid.entry_count <= 8 * 1000
    p, j, _ = grid.query(pts[:10] + 1e-6, nrm[:10])
    assert sorted(zip(p.tolist(), j.tolist())) == [(i, i) for i in range(10)]


def test_back_facing_and_cross_corner_photons_are_rejected():
    pts = np.array([[0.0, 0.0, 0.0]])
    grid = HashGrid(pts, np.array([0.1]), np.array([[0, 0, 1.0]]))
    x = np.array([[0.01, 0, 0]] * 3)
    normals = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]])   # same side, back, other wall
    p, _, _ = grid.query(x, normals)
    assert p.tolist() == [0]


def test_photons_off_the_points_tangent_plane_by_half_the_radius_are_rejected():
    """The slab test (``SLAB``): a photon on another surface that faces the same way within the
    radius (the inside of a small box's far wall behind its near wall's outside, a floor under a
    low table) is not gathered; one as far off on the plane is, and so is one on a sphere of the
    radius's size."""
    r = 0.2
    grid = HashGrid(np.zeros((1, 3)), np.array([r]), np.array([[0, 0, 1.0]]))
    x = np.array([[0.0, 0.0, -0.15], [0.0, 0.0, 0.15], [0.15, 0.0, 0.0], [0.05, 0.0, -0.09],
                  [0.0, 0.05, 0.09]])
    up = np.tile([0, 0, 1.0], (len(x), 1))
    p, _, _ = grid.query(x, up)
    assert sorted(p.tolist()) == [2, 3, 4]
    # On a sphere of radius r touching the plane at the point: every photon within r of it.
    rng = np.random.default_rng(3)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    on_sphere = d * r - [0.0, 0.0, r]
    near = np.flatnonzero(np.linalg.norm(on_sphere, axis=1) < 0.999 * r)
    p, _, _ = grid.query(on_sphere[near], np.tile([0, 0, 1.0], (len(near), 1)))
    assert len(p) == len(near)


def test_boxes_wider_than_the_offset_groups_are_found():
    """A few radii far above the median span more than GROUP_SPAN cells: listed separately."""
    rng = np.random.default_rng(11)
    pts, radii, nrm = random_points(rng, 4000, 1.0, 0.0, (0.01, 0.03))
    radii[:40] = rng.uniform(0.2, 0.5, 40)
    grid = HashGrid(pts, radii, nrm)
    assert (2 * radii / grid.cell_size).max() > GROUP_SPAN + 1
    x = pts[rng.integers(0, 4000, 3000)] + 0.05 * rng.normal(size=(3000, 3))
    xn = nrm[rng.integers(0, 4000, 3000)]
    want = query_matches_brute_force(grid, x, xn, pts, radii, nrm)
    assert len([1 for _, pj in want if pj < 40]) > 50


def test_grids_too_big_for_packed_keys_sort_by_key():
    """Clusters far apart with small radii: more than 2^31 cells, so keys are argsorted."""
    rng = np.random.default_rng(12)
    a, ra, na = random_points(rng, 1500, 1.0, 0.0, (0.01, 0.03))
    b, rb, nb = random_points(rng, 1500, 1.0, 1e4, (0.01, 0.03))
    pts, radii, nrm = np.concatenate([a, b]), np.concatenate([ra, rb]), np.concatenate([na, nb])
    radii[:10] = 0.3                                    # a few boxes wider than the offset groups
    grid = HashGrid(pts, radii, nrm)
    assert int(np.prod(grid.dims.astype(float))) >= 2 ** 31
    x = pts[rng.integers(0, 3000, 3000)] + 0.03 * rng.normal(size=(3000, 3))
    xn = nrm[rng.integers(0, 3000, 3000)]
    want = query_matches_brute_force(grid, x, xn, pts, radii, nrm)
    assert len(want) > 100 and any(pj < 10 for _, pj in want) and any(pj >= 1500 for _, pj in want)


@pytest.mark.parametrize("normals", [True, False], ids=["surfaces", "volumes"])
def test_inner_flags_mark_the_pairs_within_half_the_radius(normals):
    """``inner=True`` also says which pairs lie within r/2 (the bias correction's second gather):
    the same flags as brute force, but for pairs within float32 rounding of r/2."""
    rng = np.random.default_rng(11)
    pts, radii, nrm = random_points(rng, 2000, 1.0, 0.0, (0.02, 0.1))
    grid = HashGrid(pts, radii, nrm if normals else None)
    x = pts[rng.integers(0, 2000, 1500)] + 0.03 * rng.normal(size=(1500, 3))
    xn = nrm[rng.integers(0, 2000, 1500)] if normals else None
    p, j, _, inner = grid.query(x, xn, inner=True)
    bp, bj, binner = brute_force_query(x, xn, pts, radii, nrm if normals else None, inner=True)
    assert p.dtype == np.int64 and inner.dtype == bool and len(inner) == len(p)
    plain = grid.query(x, xn)
    assert np.array_equal(p, plain[0]) and np.array_equal(j, plain[1])     # the same pairs
    got = dict(zip(zip(p.tolist(), j.tolist()), inner.tolist()))
    want = dict(zip(zip(bp.tolist(), bj.tolist()), binner.tolist()))
    common = got.keys() & want.keys()
    inside = sum(want[k] for k in common)
    assert len(common) > 0.99 * len(want) and 0.1 * len(common) < inside < 0.5 * len(common)
    for key in common:
        if got[key] != want[key]:
            d = np.linalg.norm(x[key[0]] - pts[key[1]])
            assert abs(d - 0.5 * radii[key[1]]) < 1e-5 * radii[key[1]], (key, d, radii[key[1]])
    empty = HashGrid(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)) if normals else None)
    assert [len(a) for a in empty.query(x, xn, inner=True) if a is not None] == [0, 0, 0]
