"""Cycles' Transparent bounces (``RenderSettings.transparent_max_bounces``): a light path carries
light only if it crosses at most N transparent surfaces in all and at most N - 1 before its vertex
nearest the light (Cycles ends a camera path at the surface after its N-th crossing, where it sees
emission alone; its light samples may cross what is left).  Closed forms: a diffuse floor under a
sun at 45 degrees, seen from above through small clear sheets the sun's light does not cross, and
lit through wide ones above the camera that the camera does not look through."""
import math

import numpy as np
import pytest

from core import RenderSettings, render
from core.scene import VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION, Camera, Lights, Materials
from core.testing.scenes import MeshBuilder, _look_down

IRRADIANCE, ALBEDO = 10.0, 0.5
LIT = ALBEDO * IRRADIANCE * math.cos(math.pi / 4) / math.pi        # the floor's radiance under the sun
ALL_RAYS = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION


def sheets_over_floor(camera_sheets, light_sheets, emissive=False, lamp=False):
    """A floor of 2 x 2 at z = 0 under a sun at 45 degrees, an orthographic camera at z = 1 looking
    down at its middle (0.2 x 0.2); ``camera_sheets`` clear sheets of 0.4 x 0.4 between the camera
    and the floor (z 0.5 to 0.8: the sun's light to the middle passes beside them) and
    ``light_sheets`` clear sheets of 4 x 2 above the camera (z 2 to 3), across the sun's light to the
    middle.  ``emissive``: the floor
    glows (radiance 1) instead and no sun shines; ``lamp``: an area light of 0.5 x 0.5 at z = 0.2
    faces the camera instead, over a black floor."""
    floor = ({"name": "floor", "emission": 1.0} if emissive else
             {"name": "floor", "diffuse": 0.0 if lamp else ALBEDO})
    mats = Materials.build([floor, {"name": "sheet", "diffuse": 0.5, "opacity": 0.0}])
    m = MeshBuilder()
    m.add_quad((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), 0)
    # (a sheet off to the side, on no path to the middle: the scene has transparency at every count)
    m.add_quad((3, -1, 0.1), (4, -1, 0.1), (4, 1, 0.1), (3, 1, 0.1), 1)
    for i in range(camera_sheets):
        z = 0.5 + 0.3 * i / max(camera_sheets - 1, 1)
        m.add_quad((-0.2, -0.2, z), (0.2, -0.2, z), (0.2, 0.2, z), (-0.2, 0.2, z), 1)
    for i in range(light_sheets):
        z = 2.0 + i / max(light_sheets - 1, 1)
        m.add_quad((-3.5, -1, z), (0.5, -1, z), (0.5, 1, z), (-3.5, 1, z), 1)
    lights = None if emissive else Lights.build([{"kind": "sun", "direction": (1.0, 0.0, -1.0),
                                                  "power": IRRADIANCE}])
    if lamp:
        lights = Lights.build([{"kind": "area", "position": (0, 0, 0.2), "direction": (0, 0, 1),
                                "size": (0.5, 0.5), "power": 10.0, "visibility": ALL_RAYS}])
    cam = Camera(world_from_camera=_look_down(1.0), projection="orthographic", frame=(-0.1, 0.1, -0.1, 0.1),
                 resolution=(8, 8))
    return m.build(mats, lights, cam)


def mean(scene, limit, method="ppm"):
    settings = RenderSettings(method=method, passes=4, photons_per_pass=100_000, workers=1, seed=1,
                              transparent_max_bounces=limit, max_bounces=4)
    return float(render(scene, settings).image[..., :3].mean())


@pytest.mark.parametrize("camera_sheets, light_sheets, lit", [
    (0, 3, True), (0, 4, False),        # the light's side: up to N
    (2, 0, True), (3, 0, False),        # the camera's side: up to N - 1 (the camera path ends after N)
    (1, 2, True), (2, 2, False),        # both: N in all
])
def test_a_floor_is_lit_through_at_most_n_transparent_surfaces(camera_sheets, light_sheets, lit):
    """N = 3: lit (the sun's radiance off the floor, within 8 %) or black (exactly), and lit in every
    case without a limit (the default, 1024)."""
    scene = sheets_over_floor(camera_sheets, light_sheets)
    got = mean(scene, 3)
    if lit:
        assert got == pytest.approx(LIT, rel=0.08)
    else:
        assert got == 0.0
    assert mean(scene, RenderSettings().transparent_max_bounces) == pytest.approx(LIT, rel=0.08)


def test_an_emitter_is_seen_through_at_most_n_transparent_surfaces():
    """A glowing floor seen through 3 clear sheets with N = 3 (Cycles sees emission at the surface
    after its N-th crossing), and black through 4; at N = 0 through one (Cycles ends the path only
    after its first crossing) and not through two."""
    assert mean(sheets_over_floor(3, 0, emissive=True), 3) == pytest.approx(1.0, rel=1e-6)
    assert mean(sheets_over_floor(4, 0, emissive=True), 3) == 0.0
    assert mean(sheets_over_floor(1, 0, emissive=True), 0) == pytest.approx(1.0, rel=1e-6)
    assert mean(sheets_over_floor(2, 0, emissive=True), 0) == 0.0


@pytest.mark.parametrize("kind", ["area", "sun"])
def test_a_lamp_is_seen_through_at_most_n_transparent_surfaces(kind):
    """An area light (or a sun's disc, with no floor) seen straight through 3 clear sheets with
    N = 3 shows as through none, and is black through 4 (camera rays meet lamps as Cycles' do,
    as surfaces; a sun's disc past a ray that the limit ended: ``factor_to``)."""
    def image(sheets):
        scene = sheets_over_floor(sheets, 0, lamp=True)
        if kind == "sun":
            mats = Materials.build([{"name": "sheet", "diffuse": 0.5, "opacity": 0.0}])
            m = MeshBuilder()
            for i in range(sheets):
                z = 0.5 + 0.1 * i
                m.add_quad((-0.2, -0.2, z), (0.2, -0.2, z), (0.2, 0.2, z), (-0.2, 0.2, z), 0)
            m.add_quad((3, -1, 0.1), (4, -1, 0.1), (4, 1, 0.1), (3, 1, 0.1), 0)     # (as above)
            sun = Lights.build([{"kind": "sun", "direction": (0, 0, 1), "power": 10.0,
                                 "sun_angle": math.radians(10.0), "visibility": ALL_RAYS}])
            scene = m.build(mats, sun, scene.camera)
        return mean(scene, 3)
    bare = image(0)
    assert bare > 0.1
    assert image(3) == pytest.approx(bare, rel=1e-6)
    assert image(4) == 0.0


@pytest.mark.parametrize("camera_sheets, light_sheets, lit", [(0, 0, True), (1, 0, False), (0, 1, False)])
def test_at_zero_a_floor_is_lit_through_no_transparent_surface(camera_sheets, light_sheets, lit):
    """N = 0 (measured in Cycles: lit with no sheet on either side, black with one)."""
    got = mean(sheets_over_floor(camera_sheets, light_sheets), 0)
    assert got == pytest.approx(LIT, rel=0.08) if lit else got == 0.0


@pytest.mark.parametrize("mutation", ["paper", "exact"])
def test_the_chains_keep_to_the_limit(mutation):
    """The Markov chains (their recorded first vertices carry the counts for the exact mutation's
    resumed paths): lit through 1 + 2 sheets with N = 3, black through 2 + 2."""
    def chains(camera_sheets, light_sheets):
        settings = RenderSettings(method="amcmcppm", mutation=mutation, passes=4, photons_per_pass=100_000,
                                  workers=1, seed=2, transparent_max_bounces=3, max_bounces=4)
        return float(render(sheets_over_floor(camera_sheets, light_sheets), settings).image[..., :3].mean())
    assert chains(1, 2) == pytest.approx(LIT, rel=0.1)
    assert chains(2, 2) == 0.0


def test_the_limit_is_checked():
    with pytest.raises(ValueError, match="transparent_max_bounces"):
        RenderSettings(transparent_max_bounces=-1)
    with pytest.raises(ValueError, match="transparent_max_bounces"):
        RenderSettings(transparent_max_bounces=2000)
    assert np.isfinite(RenderSettings(transparent_max_bounces=0).bounce_limits.transparent)
