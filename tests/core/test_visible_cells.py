"""The chains' visible cells: they cover every point's gather box, keep backs out, leave lone points out
and only grow."""
import numpy as np

from core.context import RenderContext
from core.eye_pass import trace_eye_pass
from core.photon_pass import DepositTarget, path_dims, trace_photons
from core.testing.scenes import cornell_box
from core.visible_cells import VisibleCells, normal_axis


def random_points(rng, n, spread=10.0):
    x = rng.normal(0.0, spread, (n, 3)) + 1e3          # away from the origin on purpose
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    r = np.exp(rng.uniform(np.log(0.01), np.log(2.0), n))   # several levels
    return x, nrm, r


def test_normal_axis_is_the_major_axis_and_its_sign():
    n = np.random.default_rng(0).normal(size=(5000, 3))
    k = np.argmax(np.abs(n), axis=1)
    expected = 2 * k + (n[np.arange(len(n)), k] < 0)
    np.testing.assert_array_equal(normal_axis(n), expected)


def test_every_position_within_a_points_radius_is_inside():
    rng = np.random.default_rng(1)
    x, nrm, r = random_points(rng, 3000)
    cells = VisibleCells().extended(x, nrm, r, min_points=1)
    assert len(cells.levels) > 3
    for _ in range(5):
        # Anywhere in the box x +- r, with the point's own normal.
        q = x + r[:, None] * rng.uniform(-0.999, 0.999, (len(x), 3))
        assert cells.contains(q, nrm).all()


def test_the_back_and_far_away_are_outside():
    rng = np.random.default_rng(2)
    x, nrm, r = random_points(rng, 2000)
    nrm[:, 2] = np.abs(nrm[:, 2]) + 2.0                    # all facing +z most
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    cells = VisibleCells().extended(x, nrm, r, min_points=1)
    # The opposite normal has another major-axis sign: the back of a thin wall.
    assert cells.contains(x, nrm).all()
    assert not cells.contains(x, -nrm).any()
    assert not cells.contains(x + 1e3, nrm).any()


def test_the_set_only_grows_and_survives_a_worker_round_trip():
    rng = np.random.default_rng(3)
    xa, na, ra = random_points(rng, 1000)
    xb, nb, rb = random_points(rng, 1000)
    first = VisibleCells().extended(xa, na, ra, min_points=1)
    both = first.extended(xb, nb, rb, min_points=1)
    assert both.contains(xa, na).all() and both.contains(xb, nb).all()
    assert first.key_count < both.key_count
    assert first.extended(xa, na, ra, min_points=1).key_count == first.key_count          # nothing new
    assert first.base == both.base and np.array_equal(first.origin, both.origin)   # fixed by pass 1
    again = VisibleCells.from_arrays(both.to_arrays())
    q = np.concatenate([xa, xb, xa + 0.5])
    nq = np.concatenate([na, nb, na])
    np.testing.assert_array_equal(again.contains(q, nq), both.contains(q, nq))


def test_lone_points_add_nothing():
    """Points seen through a ball lens or a curved mirror lie far apart: they stay visible through
    their own deposits in every pass, but their cells would make V many times the surface seen."""
    rng = np.random.default_rng(4)
    dense = rng.uniform(0.0, 1.0, (4000, 3)) * (1.0, 1.0, 0.0)       # a square seen face on
    lone = rng.uniform(-100.0, 100.0, (30, 3)) + (0.0, 0.0, 300.0)   # far apart, far away
    up = np.tile((0.0, 0.0, 1.0), (4030, 1))
    cells = VisibleCells().extended(np.concatenate([dense, lone]), up, np.full(4030, 0.05))
    assert cells.contains(dense, up[:4000]).all()
    assert not cells.contains(lone, up[:30]).any()
    assert VisibleCells().extended(lone, up[:30], np.full(30, 0.05)).key_count == 0


def test_bad_points_are_ignored():
    cells = VisibleCells().extended(np.array([[0.0, 0, 0], [np.nan, 0, 0], [1, 1, 1]]),
                                    np.array([[0.0, 0, 1]] * 3), np.array([0.1, 0.1, 0.0]), min_points=1)
    assert cells.key_count > 0
    assert cells.contains(np.array([[0.0, 0, 0]]), np.array([[0.0, 0, 1]]))[0]
    assert VisibleCells().extended(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)).key_count == 0


def test_cells_add_visible_paths_and_change_no_deposit():
    """With cells, V is the paths with a vertex in them: here (no lone points) a superset of the
    paths that deposit; with no cells, V is empty.  The deposits are the same."""
    scene = cornell_box((24, 18))
    ctx = RenderContext(scene)
    eye = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8)
    pts = eye.points
    w, h = scene.camera.resolution
    # Gather radii of a late pass: the discs no longer cover the surfaces, the cells do.
    radius = 0.1 * pts.base_radius
    plain = DepositTarget(pts, radius, ctx.table, w * h, ctx.has_shading_normals)
    cells = VisibleCells().extended(pts.position, pts.ng, pts.base_radius)
    celled = DepositTarget(pts, radius, ctx.table, w * h, ctx.has_shading_normals, cells=cells)
    u = np.random.default_rng(1).random((4000, path_dims(8)))
    a = trace_photons(ctx, plain, u.copy(), 8, collect_pairs=True)
    b = trace_photons(ctx, celled, u.copy(), 8, collect_pairs=True)
    deposited = np.zeros(len(u), bool)
    deposited[a.pair_path] = True
    assert deposited.any()
    np.testing.assert_array_equal(a.visible, deposited)
    assert b.visible[deposited].all() and b.visible.sum() > a.visible.sum()
    # The first visible vertex can only come earlier.
    both = a.visible & b.visible
    assert (b.first_dim[both] <= a.first_dim[both]).all()
    np.testing.assert_array_equal(a.pair_path, b.pair_path)
    np.testing.assert_array_equal(a.pair_point, b.pair_point)
    np.testing.assert_allclose(a.pair_value, b.pair_value)
    # Cells alone make a path visible: with none, no path is, and the deposits stay.
    empty = DepositTarget(pts, radius, ctx.table, w * h, ctx.has_shading_normals, cells=VisibleCells())
    e = trace_photons(ctx, empty, u.copy(), 8, collect_pairs=True)
    assert not e.visible.any()
    np.testing.assert_array_equal(a.pair_path, e.pair_path)
    # A worker rebuilds the same target from plain arrays.
    again = DepositTarget.from_arrays(celled.to_arrays(), ctx.table)
    c = trace_photons(ctx, again, u.copy(), 8, collect_pairs=True)
    np.testing.assert_array_equal(b.visible, c.visible)


def test_the_bounding_box_test_changes_nothing():
    """``contains`` skips vertices outside the cells' box; inside it, every level is still asked."""
    rng = np.random.default_rng(5)
    x, nrm, r = random_points(rng, 2000)
    cells = VisibleCells().extended(x, nrm, r, min_points=1)
    q = np.concatenate([x + r[:, None] * rng.uniform(-3, 3, (len(x), 3)), rng.normal(1e3, 100.0, (4000, 3))])
    nq = np.concatenate([nrm, rng.normal(size=(4000, 3))])
    expected = np.zeros(len(q), bool)
    for lv, keys in cells.levels.items():
        expected |= np.isin(cells._keys(q, lv, normal_axis(nq)), keys)
    assert 0 < expected.sum() < len(q)
    np.testing.assert_array_equal(cells.contains(q, nq), expected)
    lo, hi = cells.bounds()
    assert (lo < x.min(axis=0)).all() and (hi > x.max(axis=0)).all()


def test_cells_keep_the_generation_they_came_in():
    """``entry`` gives the oldest generation of the cells that hold a vertex: a point's own pass, or
    an earlier one whose cells it shares; a worker's copy keeps them."""
    rng = np.random.default_rng(6)
    xa, na, ra = random_points(rng, 1000)
    xb, nb, rb = random_points(rng, 1000)
    xb += 500.0                                              # apart from the first points
    first = VisibleCells().extended(xa, na, ra, min_points=1, generation=3)
    both = first.extended(xb, nb, rb, min_points=1, generation=11)
    both = both.extended(xa, na, ra, min_points=1, generation=19)          # adds no cell
    assert first.generation == 3 and both.generation == 11
    np.testing.assert_array_equal(both.entry(xa, na), 3)
    np.testing.assert_array_equal(both.entry(xb, nb), 11)
    assert (both.entry(xa + 1e4, na) == np.iinfo(np.int64).max).all()
    again = VisibleCells.from_arrays(both.to_arrays())
    q, nq = np.concatenate([xa, xb, xa + 1e4]), np.concatenate([na, nb, na])
    np.testing.assert_array_equal(again.entry(q, nq), both.entry(q, nq))
    np.testing.assert_array_equal(both.contains(q, nq), both.entry(q, nq) <= 11)


def test_a_paths_limit_keeps_newer_cells_out_of_its_v():
    """``trace_photons``'s ``cell_limit``: a path is visible in the cells of that generation or
    older; ``entry`` is the oldest generation it met, looked for after visibility while it is
    newer than the path's ``cell_floor``.  The deposits do not change."""
    scene = cornell_box((24, 18))
    ctx = RenderContext(scene)
    eye = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8)
    pts = eye.points
    w, h = scene.camera.resolution
    left = pts.position[:, 0] < np.median(pts.position[:, 0])
    cells = VisibleCells().extended(pts.position[left], pts.ng[left], pts.base_radius[left], generation=0)
    cells = cells.extended(pts.position[~left], pts.ng[~left], pts.base_radius[~left], generation=1)
    target = DepositTarget(pts, 0.1 * pts.base_radius, ctx.table, w * h, ctx.has_shading_normals, cells=cells)
    u = np.random.default_rng(1).random((4000, path_dims(8)))
    n = len(u)
    newest = trace_photons(ctx, target, u.copy(), 8, collect_pairs=True)
    oldest = trace_photons(ctx, target, u.copy(), 8, collect_pairs=True, cell_limit=np.zeros(n, np.int64))
    floor = trace_photons(ctx, target, u.copy(), 8, collect_pairs=True, cell_limit=np.ones(n, np.int64),
                          cell_floor=np.zeros(n, np.int64))
    np.testing.assert_array_equal(newest.visible, floor.visible)
    np.testing.assert_array_equal(newest.first_dim, floor.first_dim)
    np.testing.assert_array_equal(newest.pair_value, oldest.pair_value)
    # In the older cells alone: fewer paths, each at its first vertex in them, never earlier.
    assert oldest.visible.sum() < newest.visible.sum()
    assert not (oldest.visible & ~newest.visible).any()
    both = oldest.visible
    assert (oldest.first_dim[both] >= newest.first_dim[both]).all()
    np.testing.assert_array_equal(oldest.visible, floor.entry == 0)
    np.testing.assert_array_equal(newest.visible, floor.entry <= 1)
    # Without a floor, a path visible in the newer cells at its first vertex stops looking there.
    late = newest.visible & oldest.visible & (oldest.first_dim > newest.first_dim)
    assert late.any() and (newest.entry[late] == 1).all()
