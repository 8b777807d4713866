"""Translucency (``Materials.translucent_*``, Blender's Translucent BSDF): closed forms.

A translucent lobe sends light that lands on one side of a thin surface out of the other side
with a cosine distribution (f = colour / pi).  Camera paths end on it as on a diffuse lobe; the
photons that reach a measurement point through it are the ones that land on the *other* side
of its surface (``DepositTarget`` back pairs), and photons that scatter through it go on to
light what lies behind."""
import numpy as np
import pytest

from core import RenderSettings, render
from core.scene import Materials
from core.testing.scenes import sky_over_floor, sun_through_sheet

METHODS = [dict(method="ppm"), dict(method="amcmcppm", chains=4096)]
E = 10.0                                      # the sun's irradiance


def mean_rgb(scene, seeds, passes, photons, **settings):
    """(seeds, 3) image means of ``seeds`` renders; every pass's image must be finite."""
    def check(result):
        assert np.isfinite(result.image).all()

    images = [render(scene, RenderSettings(workers=1, passes=passes, photons_per_pass=photons, seed=s,
                                           **settings), on_iteration=check).image for s in range(seeds)]
    return np.array([image[..., :3].mean(axis=(0, 1)) for image in images])


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_a_floor_that_is_diffuse_and_translucent_under_a_constant_sky_shows_both(method):
    """An open floor under a constant sky, which lights both its sides: L = (D + T) sky for
    diffuse colour D and translucent colour T (per channel), face on and grazing.  Without
    the back pairs the floor would show D sky (0.2 against 0.74 in red)."""
    sky = 1.0
    spec = {"diffuse": 0.2, "translucent": (0.9, 0.5, 0.2), "translucent_weight": 0.6}
    scene = sky_over_floor(sky=sky, material=spec)
    expected = (0.2 + 0.6 * np.array(spec["translucent"])) * sky
    got = mean_rgb(scene, 3, 8, 40_000, **method).mean(axis=0)
    # 8 seeds measured 0.994 (PPM) and 0.989 (AMCMCPPM) of D + T = 1, 0.03 apart per render.
    np.testing.assert_allclose(got, expected, rtol=0.05)


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
@pytest.mark.parametrize("tilt", [0.0, 30.0], ids=["flat", "shading_normal_30"])
def test_a_sheet_seen_from_below_shows_the_sun_through_its_translucent_lobe(method, tilt):
    """A sun at normal incidence on a sheet of diffuse 0.3 and translucent (0.6, 0.4, 0.2),
    seen from below (where nothing else lights it): L = T E cos(tilt) / pi.  With a shading
    normal tilted by ``tilt`` the pairs weigh |N_s . wi| / |N_g . wi|, as Cycles' cosine with
    the shading normal."""
    t = np.radians(tilt)
    normal = None if tilt == 0 else (np.sin(t), 0.0, np.cos(t))
    colour = np.array([0.6, 0.4, 0.2])
    scene = sun_through_sheet({"diffuse": 0.3, "translucent": tuple(colour)}, E, half=3.0,
                              shading_normal=normal)
    got = mean_rgb(scene, 4, 6, 40_000, **method)
    expected = colour * E * np.cos(t) / np.pi
    # 8 seeds measured 1.012 (PPM) and 1.003 (AMCMCPPM) of it, 0.025 apart per render.
    np.testing.assert_allclose(got.mean(axis=0), expected, rtol=0.04)


def view_factor_to_square(x, y, half, height):
    """View factor from a point (x, y, 0) facing up to the square [-half, half]^2 at ``height``
    (the four corner rectangles of the parallel-rectangle formula)."""
    def corner(a, b):
        sa, sb = np.sign(a), np.sign(b)
        a, b = np.abs(a) / height, np.abs(b) / height
        ra, rb = np.sqrt(1 + a * a), np.sqrt(1 + b * b)
        return sa * sb * (a / ra * np.arctan(b / ra) + b / rb * np.arctan(a / rb)) / (2 * np.pi)
    return (corner(half - x, half - y) + corner(half - x, half + y) + corner(half + x, half - y)
            + corner(half + x, half + y))


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_light_scattered_through_a_translucent_sheet_lights_the_floor_below(method):
    """A sun on a purely translucent sheet (T = 0.8, half-size 3 m, 1 m above a floor of
    albedo 0.5): the sheet's underside emits T E / pi, so the floor shows rho T E F(x) / pi
    with F the view factor to the sheet (0.92 at the centre); the floor's own light leaves
    through the sheet.  Photons that scatter through the lobe alone reach the floor."""
    half, rho, t = 3.0, 0.5, 0.8
    scene = sun_through_sheet({"translucent": t}, E, floor_albedo=rho, half=half)
    got = mean_rgb(scene, 3, 8, 60_000, max_bounces=4, **method)
    xs = (np.arange(8) + 0.5) / 8 * 0.4 - 0.2                        # the camera's pixel centres
    f = view_factor_to_square(xs[:, None], xs[None, :], half, 1.0).mean()
    expected = rho * t * E * f / np.pi
    assert 0.9 < f < 0.93
    # 8 seeds of 100,000 photons measured 0.988 (PPM) and 0.995 (AMCMCPPM), 0.027 and 0.014
    # apart per render.
    np.testing.assert_allclose(got.mean(axis=0), expected, rtol=0.05)


def test_translucency_round_trips_through_a_scene_file_and_old_files_get_none(tmp_path):
    scene = sun_through_sheet({"diffuse": 0.3, "translucent": (0.6, 0.4, 0.2), "translucent_weight": 0.5}, E)
    path = tmp_path / "sheet.npz"
    scene.save(path)
    loaded = type(scene).load(path)
    np.testing.assert_array_equal(loaded.materials.translucent_color, scene.materials.translucent_color)
    np.testing.assert_array_equal(loaded.materials.translucent_weight, [0.5])
    old = scene.replace(materials=Materials(**{**scene.materials.__dict__, "translucent_weight": None,
                                               "translucent_color": None})).validate()
    assert (old.materials.translucent_weight == 0).all() and (old.materials.translucent_color == 0).all()
    bad = Materials.build([{"name": "sheet", "translucent": -0.5}])
    with pytest.raises(ValueError, match="translucent_color is negative"):
        scene.replace(materials=bad).validate()


def test_back_pairs_from_the_grid_of_translucent_points_are_the_whole_grids_translucent_pairs():
    """``DepositTarget.back_grid`` holds the translucent points alone (the red wall of a Cornell
    box, half diffuse, half translucent): photons near the points, with any normal, find there
    exactly the pairs the whole grid gives them with translucent points."""
    from core.context import RenderContext
    from core.eye_pass import trace_eye_pass
    from core.photon_pass import DepositTarget
    from core.testing.scenes import cornell_box

    scene = cornell_box(resolution=(24, 24))
    m = scene.materials
    m.diffuse_weight[1], m.translucent_weight[1], m.translucent_color[1] = 0.5, 0.5, (0.6, 0.2, 0.2)
    ctx = RenderContext(scene.validate())
    pts = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8).points
    target = DepositTarget(pts, pts.base_radius, ctx.table, 24 * 24, ctx.has_shading_normals)
    assert target.translucent is not None and 0 < target.translucent.mean() < 0.5
    grid, ids = target.back_grid
    assert grid is not target.grid and np.array_equal(ids, np.flatnonzero(target.translucent))
    rng = np.random.default_rng(1)
    k = rng.integers(0, pts.count, 20_000)
    x = pts.position[k] + rng.normal(scale=0.03, size=(len(k), 3))
    n = np.where(rng.random((len(k), 1)) < 0.5, 1.0, -1.0) * pts.ng[k].astype(np.float64)
    pi, pj, _ = grid.query(x, n)
    got = set(zip(pi.tolist(), ids[pj].tolist()))
    wi, wj, _ = target.grid.query(x, n)
    keep = target.translucent[wj]
    want = set(zip(wi[keep].tolist(), wj[keep].tolist()))
    assert len(want) > 1000 and got == want


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_a_translucent_colour_from_a_program_shows_where_the_light_comes_through(method):
    """The sunlit sheet seen from below, its translucent colour a program: A where object x < 0,
    B beyond (``translucent_program``).  Each side's outer quarter of the view shows its own
    T E / pi: the back pairs take the colour at the point; the image's mean alone would not
    tell a program from its mean."""
    a, b = np.array([0.9, 0.6, 0.3]), np.array([0.2, 0.8, 0.4])
    x = {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}
    program = {"op": "mix_color", "blend": "MIX", "a": a.tolist(), "b": b.tolist(),
               "fac": {"op": "math", "operation": "GREATER_THAN", "a": x, "b": 0.0}}
    from core.testing.scenes import with_one_object
    plain = sun_through_sheet({"translucent": 1.0}, E, half=3.0)
    mats = Materials.build([{"name": "sheet", "translucent_program": program}])
    scene = with_one_object(plain.replace(materials=mats)).validate()
    assert scene.materials.translucent_weight[0] == 1.0
    images = [render(scene, RenderSettings(workers=1, passes=6, photons_per_pass=40_000, seed=s,
                                           initial_radius_px=1.0, **method)).image for s in range(3)]
    left = np.mean([im[:, :2, :3].mean(axis=(0, 1)) for im in images], axis=0)
    right = np.mean([im[:, -2:, :3].mean(axis=(0, 1)) for im in images], axis=0)
    np.testing.assert_allclose(left, a * E / np.pi, rtol=0.06)
    np.testing.assert_allclose(right, b * E / np.pi, rtol=0.06)
