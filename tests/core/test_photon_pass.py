"""The photon tracer: a deterministic function of its primary sample; resuming at a vertex."""
import numpy as np

from core.context import RenderContext
from core.eye_pass import trace_eye_pass
from core.photon_pass import DepositTarget, PointSums, bounce_offset, path_dims, trace_photons
from core.testing.scenes import cornell_box, glass_ceiling_room, hole_mirror_glass, with_one_object


def setup(scene):
    ctx = RenderContext(scene)
    eye = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8)
    w, h = scene.camera.resolution
    # Wide radii so that many paths are visible.
    target = DepositTarget(eye.points, eye.points.base_radius * 3, ctx.table, w * h, ctx.has_shading_normals)
    return ctx, target


def pair_set(batch, rows_filter=None):
    out = set()
    for p, j, b, v in zip(batch.pair_path.tolist(), batch.pair_point.tolist(), batch.pair_bounce.tolist(),
                          batch.pair_value.tolist()):
        out.add((p, j, b, tuple(np.round(v, 9))))
    return out


def test_the_same_sample_gives_the_same_path():
    # (Not glass_ceiling_room at this size: its few visible paths of 4000 reached its points only
    # through the gather's sphere far off their plane, which the slab test rejects since stop 77.)
    ctx, target = setup(hole_mirror_glass((24, 18)))
    u = np.random.default_rng(1).random((4000, path_dims(8)))
    a = trace_photons(ctx, target, u.copy(), 8, collect_pairs=True)
    b = trace_photons(ctx, target, u.copy(), 8, collect_pairs=True)
    assert a.visible.any()
    np.testing.assert_array_equal(a.visible, b.visible)
    assert pair_set(a) == pair_set(b)


def brushed_cornell_box(resolution):
    """The Cornell box with its diffuse walls half an anisotropic glossy (radial tangents about
    the box's vertical axis): a resumed path scatters from its first visible vertex in that
    vertex's recorded tangent frame."""
    scene = cornell_box(resolution)
    m = scene.materials
    on = (m.diffuse_weight > 0) & ~(m.emission > 0).any(axis=1)
    m.diffuse_weight[on] *= 0.5
    m.glossy_weight[on], m.glossy_color[on], m.glossy_roughness[on], m.glossy_stretch[on] = 0.5, 0.8, 0.4, 3.0
    lo, hi = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
    return with_one_object(scene, (0.5 * (lo + hi), 0.5 * (hi - lo))).validate()


def test_resuming_at_the_first_visible_vertex_reproduces_the_suffix():
    # (The Cornell box's paths are nearly all visible, with many pairs each: fewer of them.)
    for scene, paths in ((glass_ceiling_room((32, 24)), 100000), (hole_mirror_glass((24, 18)), 20000),
                         (brushed_cornell_box((24, 18)), 1000)):
        ctx, target = setup(scene)
        rng = np.random.default_rng(2)
        u = rng.random((paths, path_dims(8)))
        full = trace_photons(ctx, target, u, 8, collect_pairs=True)
        vis = np.flatnonzero(full.visible)
        assert len(vis) > 20
        # Redraw every dimension after the first visible vertex, then trace fully and resumed.
        v = u[vis].copy()
        for i, start in enumerate(full.first_dim[vis]):
            v[i, start:] = rng.random(v.shape[1] - start)
        again = trace_photons(ctx, target, v.copy(), 8, collect_pairs=True)
        resumed = trace_photons(ctx, target, v.copy(), 8, collect_pairs=True,
                                resume={k: a[vis] for k, a in full.first.items()})
        assert again.visible.all() and resumed.visible.all()
        np.testing.assert_array_equal(again.first_dim, full.first_dim[vis])
        np.testing.assert_array_equal(resumed.first_dim, full.first_dim[vis])
        first_bounce = (again.first_dim - 6) // 4
        suffix = again.pair_bounce > first_bounce[again.pair_path]
        expected = {(p, j, b, tuple(np.round(x, 9))) for p, j, b, x, s in
                    zip(again.pair_path.tolist(), again.pair_point.tolist(), again.pair_bounce.tolist(),
                        again.pair_value.tolist(), suffix.tolist()) if s}
        assert pair_set(resumed) == expected
        assert resumed.rays < again.rays
        # Fresh paths and resumed ones in one batch: each part as if traced on its own.
        w = rng.random((min(3000, paths), u.shape[1]))
        alone = trace_photons(ctx, target, w.copy(), 8, collect_pairs=True)
        both = trace_photons(ctx, target, np.concatenate([w, v]), 8, collect_pairs=True,
                             resume={k: a[vis] for k, a in full.first.items()})
        np.testing.assert_array_equal(both.visible, np.concatenate([alone.visible, resumed.visible]))
        np.testing.assert_array_equal(both.first_dim, np.concatenate([alone.first_dim, resumed.first_dim]))
        shifted = {(p + len(w), j, b, x) for p, j, b, x in pair_set(resumed)}
        assert pair_set(both) == pair_set(alone) | shifted
        assert both.rays == alone.rays + resumed.rays


def test_low_dimension_refresh_redraws_only_after_the_first_visible_vertex():
    ctx, target = setup(glass_ceiling_room((24, 18)))
    u = np.random.default_rng(3).random((5000, path_dims(8)))
    before = u.copy()
    batch = trace_photons(ctx, target, u, 8, refresh_rng=np.random.default_rng(4), collect_pairs=True)
    vis = np.flatnonzero(batch.visible)
    assert len(vis)
    for i in vis[:200]:
        start = batch.first_dim[i]
        np.testing.assert_array_equal(u[i, :start], before[i, :start])
        assert (u[i, start:] != before[i, start:]).all()
    np.testing.assert_array_equal(u[~batch.visible], before[~batch.visible])
    assert (batch.first_dim[vis] >= bounce_offset(0)).all()


def test_point_sums_equal_a_direct_accumulation():
    """Pairs added in groups of every size (some past the splat threshold) sum like np.add.at."""
    rng = np.random.default_rng(3)
    m = 500
    sums = PointSums(m, min_pairs=0)                    # threshold = m pairs
    want = np.zeros((m, 3))
    for k in (0, 1, 7, 499, 500, 1200, 3, 800, 2):
        j = rng.integers(0, m, k)
        v = rng.random((3, k))
        sums.add(j, list(v))
        np.add.at(want, j, v.T)
    sums.flush()
    sums.flush()                                         # nothing waiting: no change
    np.testing.assert_allclose(sums.total, want, rtol=1e-12)
    assert want.sum() > 0


def test_photons_summed_across_calls_equal_one_call():
    """A PointSums shared by several batches (as a pass uses it) gives the sums of one batch."""
    ctx, target = setup(glass_ceiling_room((24, 18)))
    u = np.random.default_rng(4).random((6000, path_dims(8)))
    whole = trace_photons(ctx, target, u.copy(), 8)
    sums = PointSums(target.points.count)
    for part in np.array_split(u, 3):
        batch = trace_photons(ctx, target, part.copy(), 8, sums=sums)
        assert batch.sums is None
    sums.flush()
    assert whole.sums.sum() > 0
    np.testing.assert_allclose(sums.total, whole.sums, rtol=1e-9, atol=1e-12)


def test_volume_pairs_of_even_scattering_share_one_phase_value():
    """Media of anisotropy 0 give the volume pairs one phase value, hg_phase's at g = 0 to the bit;
    other media give each pair its own (the same pairs either way).  (``media``: rows of
    ``core/phase.py`` since stop 51.)"""
    from core.photon_pass import ISOTROPIC_PHASE
    from core.sampling import hg_phase
    from core.testing.scenes import corner_in_world_fog
    assert ISOTROPIC_PHASE == hg_phase(np.array([-1.0, 0.3, 1.0]), 0.0)[1]
    rng = np.random.default_rng(5)
    ctx = RenderContext(corner_in_world_fog((24, 18)))          # world fog of g = -0.2
    eye = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8)
    vol = eye.volume
    x = vol.position[rng.integers(0, vol.count, 400)] + 0.01 * rng.normal(size=(400, 3))
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    found = []
    from core.phase import resolve
    m = len(ctx.anisotropy)
    even = resolve(np.zeros(m), np.zeros(m), np.zeros((m, 3)))
    for media in (even, ctx.phase):
        target = DepositTarget(eye.points, eye.points.base_radius, ctx.table, 24 * 18,
                               ctx.has_shading_normals, volume=vol, volume_radius=vol.base_radius,
                               media=media)
        found.append(target.volume_pairs(x, d))
    (pi, pj, phase), (pi2, pj2, phase2) = found
    assert len(pi) > 100 and ctx.anisotropy.any()
    assert np.ndim(phase) == 0 and phase == ISOTROPIC_PHASE
    np.testing.assert_array_equal(pi, pi2)
    np.testing.assert_array_equal(pj, pj2)
    assert phase2.shape == pi.shape and phase2.std() > 0
