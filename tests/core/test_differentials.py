"""Ray differentials against finite differences: the width of a pixel's beam through curved
mirrors and glass, measured by tracing the eye pass again with the image shifted a fraction
of a pixel (same seed: the same jitter and the same choices between reflection and refraction)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from core.context import RenderContext
from core.differentials import MIN_WIDTH_RATIO
from core.eye_pass import trace_eye_pass
from core.scene import Camera, Lights, Materials
from core.testing.scenes import MeshBuilder

RADIUS_PX = 4.0
DELTA = 0.01          # pixels


def ball_in_room(material, smooth=True, lens_mm=85.0):
    """A ball of ``material`` in the middle of a closed diffuse room (no camera ray leaves it)."""
    mats = Materials.build([{"name": "room", "diffuse": 0.5}, dict(material, name="ball")])
    m = MeshBuilder()
    m.add_box((-4, -4, -4), (4, 4, 4), 0)
    m.add_sphere((0.0, 0.0, 0.0), 1.0, 1, n_theta=48, n_phi=96, smooth=smooth)
    lights = Lights.build([{"kind": "point", "position": (0, 0, 3.5), "power": 100.0}])
    cam = Camera.look_at((0.3, -3.5, 0.2), (0, 0, 0), lens_mm=lens_mm, resolution=(40, 40))
    return m.build(mats, lights, cam, smooth=smooth)


def _points(scene, seed):
    ctx = RenderContext(scene)
    eye = trace_eye_pass(ctx, np.random.default_rng(seed), RADIUS_PX, 8)
    return eye.points


def _shifted(scene, dx, dy):
    cam = scene.camera
    x0, x1, y0, y1 = cam.frame
    w, h = cam.resolution
    sx, sy = dx * (x1 - x0) / w, -dy * (y1 - y0) / h       # rows count downwards
    return dataclasses.replace(scene, camera=dataclasses.replace(cam, frame=(x0 + sx, x1 + sx, y0 + sy, y1 + sy)))


def width_ratios(scene, seed=3):
    """Per pixel whose point is on the room's walls: the eye pass's width over the finite-difference
    width, and whether the pixel's path went through the ball (its point lies off the straight line)."""
    base = _points(scene, seed)
    moved = [_points(_shifted(scene, DELTA, 0), seed), _points(_shifted(scene, 0, DELTA), seed)]
    axes = []
    for pts in moved:
        same, i, j = np.intersect1d(base.pixel_ids, pts.pixel_ids, return_indices=True)
        a = np.full((len(base.pixel_ids), 3), np.nan)
        ok = base.mat_ids[i] == pts.mat_ids[j]
        a[i[ok]] = (pts.position[j[ok]] - base.position[i[ok]]) / DELTA
        axes.append(a)
    wo = base.wo.astype(np.float64)
    across = [a - np.sum(a * wo, axis=1)[:, None] * wo for a in axes]
    fd = np.sqrt(0.5 * (np.sum(across[0] ** 2, axis=1) + np.sum(across[1] ** 2, axis=1)))
    ours = base.base_radius / RADIUS_PX
    cam = scene.camera
    eye = cam.world_from_camera[:3, 3]
    to_eye = eye - base.position
    straight = np.linalg.norm(np.cross(to_eye, wo), axis=1) < 1e-6 * np.linalg.norm(to_eye, axis=1)
    keep = (base.mat_ids == 0) & np.isfinite(fd) & (fd > 0)
    return ours[keep] / fd[keep], ~straight[keep]


@pytest.mark.parametrize("material", [{"mirror": 1.0}, {"dielectric": 1.0, "ior": 1.5}],
                         ids=["mirror", "glass"])
def test_width_through_a_smooth_ball_matches_finite_differences(material):
    ratio, through = width_ratios(ball_in_room(material))
    assert through.sum() > 200, "the ball must fill much of the view"
    r = ratio[through]
    # Rays near the ball's rim graze it and spread without bound; most match within a few per cent.
    assert abs(np.median(r) - 1.0) < 0.02, np.median(r)
    assert np.mean(np.abs(r - 1.0) < 0.1) > 0.8, np.quantile(r, [0.1, 0.5, 0.9])
    # Seen directly (the corners), the width stays footprint x distance; the footprint leaves out
    # the obliquity of off-axis pixels, 1 / sqrt(1 - d_x^2), 2 % in the corners.
    assert np.all(np.abs(ratio[~through] - 1.0) < 0.03)


def test_the_straight_line_width_fails_this_check(monkeypatch):
    """Without the differentials (width floored at MIN_WIDTH_RATIO x footprint x path length) the
    same pixels come out several times too narrow: the check above can fail."""
    import core.eye_pass
    monkeypatch.setattr(core.eye_pass, "beam_width", lambda diff, d, t: np.zeros(len(t)))
    ratio, through = width_ratios(ball_in_room({"mirror": 1.0}))
    straight = ratio[through] / MIN_WIDTH_RATIO
    assert np.median(straight) < 0.5, np.median(straight)


def test_flat_facets_act_as_flat_mirrors():
    """Without shading normals each facet is a flat mirror: the widths still match the finite
    differences (which now see no change of normal within a facet)."""
    ratio, through = width_ratios(ball_in_room({"mirror": 1.0}, smooth=False))
    r = ratio[through]
    assert abs(np.median(r) - 1.0) < 0.02, np.median(r)
