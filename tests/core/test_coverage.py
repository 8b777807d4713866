"""Gathers near edges (``core/coverage.py``, ``RenderSettings.edge_coverage``).

A point near the edge of its surface gathers photons over a disc that reaches off the surface;
dividing by the covered share of the disc keeps it as bright as the surface is.  The scenes are
lit evenly by a sun straight above, so every lit pixel of a surface of albedo a shows a E / pi.
"""
from __future__ import annotations

import numpy as np
import pytest

from core import RenderSettings, render
from core.context import RenderContext
from core.coverage import disc_coverage, edge_candidates, point_coverage
from core.eye_pass import trace_eye_pass
from core.scene import Camera, Lights, Materials
from core.testing.scenes import MeshBuilder, _look_down, cornell_box, furnace_sphere, with_one_object

ALBEDO, SUN = 0.5, 10.0
EXPECTED = ALBEDO * SUN / np.pi
RES = 96                       # pixels across 1.2 m: the 1 m floor spans columns 8 to 87


def floor_scene(wall=None, frame=0.6, opacity_program=None):
    """A 1 m floor under a sun straight above, seen from above by an orthographic camera over
    2 ``frame`` m.  ``wall``: "end", a black wall 0.3 m high along the floor's edge x = 0.5;
    "middle", one along x = 0 on the floor that runs on under it (black: no light bounces
    between it and the floor, which has the sun's light alone)."""
    m = MeshBuilder()
    m.add_quad((-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0), 0)
    if wall is not None:
        x = 0.5 if wall == "end" else 0.0
        m.add_quad((x, -0.5, 0), (x, 0.5, 0), (x, 0.5, 0.3), (x, -0.5, 0.3), 1)
    lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": SUN}])
    cam = Camera(world_from_camera=_look_down(2.0), projection="orthographic",
                 frame=(-frame, frame, -frame, frame), resolution=(RES, RES))
    plain = [{"name": "floor", "diffuse": ALBEDO}, {"name": "block", "diffuse": 0.0}]
    scene = m.build(Materials.build(plain), lights, cam)
    if opacity_program is not None:
        mats = Materials.build([{**plain[0], "opacity_program": opacity_program}, plain[1]])
        scene = with_one_object(scene).replace(materials=mats)
    return scene.validate()


def image(scene, coverage, **kw):
    # (the photons' gathers near edges: their direct light, which light samples would take instead)
    settings = dict(method="ppm", passes=16, photons_per_pass=50000, workers=1, edge_coverage=coverage,
                    direct_light="photons")
    settings.update(kw)
    return render(scene, RenderSettings(**settings)).image[..., 0] / EXPECTED


def test_the_floors_edges_and_corners_keep_their_brightness():
    """The floor's first pixels inside its edges: about 0.7 of the expected value without the
    coverage (the disc half off the floor), within 6 % with it; its corners (a quarter of the
    disc on the floor) 0.4-0.5 without, 1.02-1.12 with (a share that small, estimated from 32
    probes, errs high: 1 / c is convex); the middle the same either way."""
    scene = floor_scene()
    plain, covered = image(scene, False), image(scene, True)
    inner = slice(10, 86)
    for img in (plain, covered):
        assert img[30:66, 30:66].mean() == pytest.approx(1.0, abs=0.02)
    edges = lambda img: np.concatenate([img[inner, 8], img[inner, 87], img[8, inner], img[87, inner]])  # noqa: E731
    corners = lambda img: np.array([img[8, 8], img[8, 87], img[87, 8], img[87, 87]])  # noqa: E731
    assert edges(plain).mean() < 0.8 and corners(plain).max() < 0.6
    assert edges(covered).mean() == pytest.approx(1.0, abs=0.06)
    np.testing.assert_allclose(corners(covered), 1.0, atol=0.16)
    # Off the floor nothing is drawn either way.
    assert covered[:, :8].max() == 0.0 and covered[:8].max() == 0.0


def test_a_floor_that_ends_at_a_wall_keeps_its_brightness_there():
    """The floor's last pixels before the wall it ends at: the disc reaches beyond the wall,
    where there is no floor."""
    plain, covered = image(floor_scene("end"), False), image(floor_scene("end"), True)
    assert plain[10:86, 87].mean() < 0.8
    assert covered[10:86, 87].mean() == pytest.approx(1.0, abs=0.06)


def test_a_thin_wall_on_a_floor_that_runs_on_under_it_changes_nothing():
    """A wall of no thickness standing on the floor, which is lit on both sides: the gathers
    beside it take the photons on its other side too (the grid tests no visibility), so the
    disc is whole, as the probes (which look for surface, not for walls) find."""
    plain, covered = image(floor_scene("middle"), False), image(floor_scene("middle"), True)
    beside = [np.concatenate([img[10:86, 47], img[10:86, 48]]).mean() for img in (plain, covered)]
    assert beside[0] == pytest.approx(1.0, abs=0.05)
    assert beside[1] == pytest.approx(beside[0], rel=0.02)


def test_an_alpha_cut_edge_is_an_edge():
    """The floor cut away by its opacity where x > 0: the probes that land there are not covered
    (no photon stops where the opacity is 0), so the cut edge keeps its brightness too."""
    x = {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}
    cut = {"op": "math", "operation": "LESS_THAN", "a": x, "b": 0.0}
    scene = floor_scene(opacity_program=cut)
    plain, covered = image(scene, False), image(scene, True)
    column = 47                   # the last column with x < 0
    assert plain[20:76, column].mean() < 0.75
    assert covered[20:76, column].mean() == pytest.approx(1.0, abs=0.06)
    assert covered[20:76, 49:80].max() == 0.0


def test_probes_go_on_through_surfaces_they_do_not_land_on():
    """Over the floor's middle, 2 cm up, lies a sheet cut away everywhere (opacity 0) or a panel
    tilted 45 degrees: photons reach the floor through the first and the grid gathers through
    the second, so the probes go on through both and find the disc whole (before they stopped
    there: the share 0.25, four times too bright)."""
    for opacity, tilt in ((0.0, 0.0), (1.0, 0.5)):
        m = MeshBuilder()
        m.add_quad((-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0), 0)
        m.add_quad((-0.3, -0.3, 0.02), (0.3, -0.3, 0.02 + 0.6 * tilt), (0.3, 0.3, 0.02 + 0.6 * tilt),
                   (-0.3, 0.3, 0.02), 1)
        lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": SUN}])
        cam = Camera(world_from_camera=_look_down(2.0), projection="orthographic",
                     frame=(-0.6, 0.6, -0.6, 0.6), resolution=(8, 8))
        mats = Materials.build([{"name": "floor", "diffuse": ALBEDO},
                                {"name": "sheet", "diffuse": ALBEDO, "opacity": opacity}])
        ctx = RenderContext(m.build(mats, lights, cam).validate())
        points = np.array([[0.0, 0.0, 0.0], [0.05, -0.1, 0.0]])
        up = np.tile([0.0, 0.0, 1.0], (2, 1))
        share = disc_coverage(ctx, points, up, np.full(2, 0.1), np.random.default_rng(0))
        np.testing.assert_array_equal(share, 1.0)


def test_the_inside_of_a_surface_is_untouched():
    """A camera that sees only the floor's inside: no point is near an edge, the coverage is not
    even computed, and the image is the same to the bit."""
    scene = floor_scene(frame=0.3)
    ctx = RenderContext(scene)
    pts = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8).points
    assert not edge_candidates(pts, RES, RES, 5.0).any()
    assert point_coverage(ctx, pts, pts.base_radius, RES, RES, 5.0, np.random.default_rng(1)) == (None, None)
    np.testing.assert_array_equal(image(scene, False, passes=3), image(scene, True, passes=3))


def test_spheres_are_whole():
    """Inside a sphere the area within a ball about a point is pi r^2 at any radius (Archimedes):
    with radii of a third of the sphere's the probes find every disc whole, and the furnace
    renders the same to the bit.  (At radii near the sphere's own the grid's normal test itself
    leaves out the sphere beyond 45 degrees, and the probes, which apply it too, find less.)"""
    scene = furnace_sphere(resolution=(16, 16))
    settings = dict(method="ppm", passes=4, photons_per_pass=20_000, max_bounces=20, workers=1)
    a = render(scene, RenderSettings(edge_coverage=False, **settings)).image
    b = render(scene, RenderSettings(edge_coverage=True, **settings)).image
    np.testing.assert_array_equal(a, b)
    assert abs(a[..., :3].mean() - 1.0) < 0.05


def test_candidates_hold_every_point_whose_disc_is_cut():
    """The image-space filter is conservative: on the Cornell box (blocks, corners, the light)
    every point that probes find cut is among the candidates, which are a minority."""
    w, h = 192, 144
    ctx = RenderContext(cornell_box((w, h)))
    pts = trace_eye_pass(ctx, np.random.default_rng(0), 4.0, 8).points
    full = disc_coverage(ctx, pts.position, pts.ng.astype(np.float64), pts.base_radius, np.random.default_rng(1))
    candidates = edge_candidates(pts, w, h, 5.0)
    cut = full < 1.0
    assert cut.sum() > 100
    assert candidates[cut].all()
    assert candidates.mean() < 0.75
    assert np.isfinite(full).all() and full.min() >= 0.25 and full.max() == 1.0


def test_edge_coverage_is_validated():
    with pytest.raises(ValueError, match="edge_coverage"):
        RenderSettings(edge_coverage=1)
