"""core.sky (Blender 5.0's Sky Texture as Cycles evaluates it): properties and values from Cycles.

The CYCLES values are pixels of Blender 5.0.1 Cycles renders (tests/addon/test_sky_texture.py's
panorama, sun disc off, float32 EXR) at the listed world directions; the disc irradiances are Cycles'
disc pixels integrated over the disc in that file's disc test.  That test measures differences of at
most ~5e-4 (relative to the pixel's largest channel) on these settings, hence the 1e-3 bounds.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from core import sky

SUN_SIZE = 0.009512044489383698         # the node's default (float32) sun size
DIRECTIONS = np.array([
    [-0.08409403263160259, 0.10507216937912263, 0.99090263542778],        # near the zenith
    [0.011866288785817207, 0.9669036594949919, 0.25486565960451457],      # next to the sun (15 deg, +Y)
    [-0.2546929587056662, -0.9663212328853688, 0.03680722294135893],      # horizon, away from the sun
    [0.9992471374506882, 0.03680445142516553, 0.012271538285719884],      # horizon, 90 deg from it
    [0.012248444636124662, 0.9980429564419312, -0.06132073630220859],     # just below, under the sun
    [0.9658941275199557, -0.20448135543120277, -0.15885814333386133],     # below the horizon
    [-0.5908717093209636, -0.20327322264796174, -0.7807372285720945]])    # towards the ground
CYCLES = {
    "ms_15": (dict(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(15), sun_rotation=0.0), [
        (0.6620765924453735, 1.3399571180343628, 2.7786970138549805),
        (28.844512939453125, 29.224468231201172, 27.213851928710938),
        (10.684686660766602, 11.893129348754883, 10.568398475646973),
        (7.694687366485596, 7.549860954284668, 7.07547664642334),
        (3.5360302925109863, 3.3344409465789795, 2.8420863151550293),
        (0.08978016674518585, 0.1385725438594818, 0.248829647898674),
        (0.018337467685341835, 0.02894960157573223, 0.05247171223163605)]),
    "ss_15": (dict(sky_type="SINGLE_SCATTERING", sun_elevation=math.radians(15), sun_rotation=0.0), [
        (0.5811423063278198, 0.9191766977310181, 1.528746485710144),
        (32.129703521728516, 26.494796752929688, 19.326889038085938),
        (6.35687255859375, 6.468023300170898, 4.329074382781982),
        (3.104362726211548, 2.7200698852539062, 1.6076180934906006),
        (39.273895263671875, 23.005373001098633, 7.783873558044434),
        (0.47189339995384216, 0.4213564991950989, 0.2626504600048065),
        (0.0, 0.0, 0.0)]),
    "preetham": (dict(sky_type="PREETHAM", sun_elevation=0.0, sun_rotation=0.0, sun_direction=(0.3, 0.5, 0.8),
                      turbidity=2.2), [
        (0.25415506958961487, 0.3826029598712921, 0.7382782697677612),
        (0.6921177506446838, 0.8722369074821472, 1.3235862255096436),
        (0.67411208152771, 0.6576324105262756, 0.7820098996162415),
        (0.8903006315231323, 0.7761036157608032, 0.8905187249183655),
        (1.0055327415466309, 0.852215588092804, 0.9534236192703247),
        (0.7484855055809021, 0.6837770342826843, 0.8098402619361877),
        (0.7523388266563416, 0.7110038995742798, 0.8130868077278137)]),
}
# Cycles' disc pixels (minus the sky) integrated over the disc, W m^-2 (160 x 160 pixels over 1.3 disc
# diameters: a midpoint rule within ~1e-4 of the exact integral).
CYCLES_DISC_IRRADIANCE = [
    (dict(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(15), sun_rotation=0.0,
          sun_size=SUN_SIZE), (126.6945, 93.6487, 53.0051)),
    # The smallest disc (0.0003 is clamped to 0.0005): Cycles' float32 solid angle is 1.9x too large.
    (dict(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(15), sun_rotation=0.0,
          sun_size=0.0003), (66.4934, 49.1520, 27.8213)),
    (dict(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(15), sun_rotation=math.radians(75),
          sun_size=0.02, sun_intensity=2.5, air_density=1.5, aerosol_density=3.0, ozone_density=0.5),
     (284.5010, 182.6256, 69.2633)),
    # A low red sun: its blue is outside Rec.709 and Cycles clamps after adding it to the sky.
    (dict(sky_type="SINGLE_SCATTERING", sun_elevation=math.radians(2), sun_rotation=math.radians(200),
          altitude=2000.0, air_density=1.5, aerosol_density=3.0, ozone_density=0.5),
     (33.2015, 9.9926, 0.0)),
]


@pytest.fixture(scope="module")
def cache():
    return sky.SkyTextureCache()


def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def ring(sun, elevations, azimuth_offset):
    """Directions (n, 3) at ``elevations`` (radians) and the sun's azimuth plus ``azimuth_offset``."""
    phi = math.atan2(sun[1], sun[0]) + azimuth_offset
    e = np.asarray(elevations, np.float64)
    return np.stack([np.cos(e) * math.cos(phi), np.cos(e) * math.sin(phi), np.sin(e)], -1)


# ---------------------------------------------------------------------- sun direction
def test_sun_direction_from_elevation_and_rotation():
    r = math.radians
    assert np.allclose(sky.sun_direction_from_angles(0.0, 0.0), [0, 1, 0], atol=1e-12)
    assert np.allclose(sky.sun_direction_from_angles(0.0, r(90)), [1, 0, 0], atol=1e-12)
    assert np.allclose(sky.sun_direction_from_angles(0.0, r(-90)), [-1, 0, 0], atol=1e-12)
    assert np.allclose(sky.sun_direction_from_angles(r(90) - 1e-9, 1.0), [0, 0, 1], atol=1e-8)
    e, rot = r(30), r(40)
    expected = [math.cos(e) * math.sin(rot), math.cos(e) * math.cos(rot), math.sin(e)]
    assert np.allclose(sky.sun_direction_from_angles(e, rot), expected, atol=1e-12)
    # Past the zenith the elevation folds back and the azimuth turns half round (simplify_settings).
    assert np.allclose(sky.sun_direction_from_angles(r(120), r(30)),
                       sky.sun_direction_from_angles(r(60), r(210)), atol=1e-12)
    assert np.allclose(sky.sun_direction_from_angles(r(15) + 4 * math.pi, r(30) - 6 * math.pi),
                       sky.sun_direction_from_angles(r(15), r(30)), atol=1e-12)
    e, rot = sky.cycles_sun_angles(r(120), r(30))
    assert e == pytest.approx(r(60)) and rot == pytest.approx(2 * math.pi - r(210))


def test_disc_direction_and_angle():
    disc = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=0.4, sun_rotation=-2.0)
    assert np.allclose(disc["direction"], sky.sun_direction_from_angles(0.4, -2.0))
    assert disc["angle"] == SUN_SIZE
    small = sky.sun_disc(sky_type="SINGLE_SCATTERING", sun_size=1e-5, sun_elevation=0.4, sun_rotation=0.0)
    assert small["angle"] == sky.MIN_SUN_SIZE
    assert sky.sun_disc(sky_type="PREETHAM", sun_elevation=0.4, sun_rotation=0.0) is None
    assert sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_disc=False, sun_elevation=0.4,
                        sun_rotation=0.0) is None


# ---------------------------------------------------------------------- sky
@pytest.mark.parametrize("case", list(CYCLES))
def test_values_from_cycles(cache, case):
    settings, expected = CYCLES[case]
    ours = sky.sky_radiance(DIRECTIONS, **settings, cache=cache)
    expected = np.array(expected)
    scale = np.maximum(expected.max(axis=1, keepdims=True), 1e-3)
    assert np.all(np.abs(ours - expected) / scale < 1e-3), (ours, expected)


@pytest.mark.parametrize("sky_type", ["MULTIPLE_SCATTERING", "SINGLE_SCATTERING", "PREETHAM"])
def test_symmetric_about_the_suns_azimuth(cache, sky_type):
    e, rot = math.radians(15), 0.0                      # the CYCLES settings: their textures are cached
    sun = sky.sun_direction_from_angles(e, rot)
    elevations = np.radians([80, 40, 10, 1, -2, -30])
    for offset in (0.1, 1.0, 2.5):
        left = sky.sky_radiance(ring(sun, elevations, offset), sky_type=sky_type, sun_elevation=e,
                                sun_rotation=rot, sun_direction=sun, cache=cache)
        right = sky.sky_radiance(ring(sun, elevations, -offset), sky_type=sky_type, sun_elevation=e,
                                 sun_rotation=rot, sun_direction=sun, cache=cache)
        assert np.allclose(left, right, rtol=1e-9, atol=1e-12)
        assert np.ptp(luminance(left)) > 0.1 * luminance(left).max()


@pytest.mark.parametrize("sky_type", ["MULTIPLE_SCATTERING", "SINGLE_SCATTERING", "PREETHAM"])
def test_horizon_brightens_and_ground_is_darker(cache, sky_type):
    """At right angles to the sun the sky brightens monotonically from near the zenith down to a few
    degrees above the horizon; the physical skies are much darker below the horizon."""
    e, rot = math.radians(15), 0.0
    sun = sky.sun_direction_from_angles(e, rot)
    elevations = np.radians([80, 70, 50, 30, 15, 8])
    lum = luminance(sky.sky_radiance(ring(sun, elevations, math.pi / 2), sky_type=sky_type, sun_elevation=e,
                                     sun_rotation=rot, sun_direction=sun, cache=cache))
    assert np.all(np.diff(lum) > 0), lum
    if sky_type != "PREETHAM":
        below = ring(sun, np.radians([-20, -60]), math.pi / 2)
        ground = luminance(sky.sky_radiance(below, sky_type=sky_type, sun_elevation=e, sun_rotation=rot,
                                            cache=cache))
        assert np.all(ground < 0.05 * lum[-1]), (ground, lum)


def test_hosek_wilkie_is_not_supported():
    with pytest.raises(NotImplementedError):
        sky.sky_radiance(DIRECTIONS, sky_type="HOSEK_WILKIE", sun_elevation=0.3, sun_rotation=0.0)


# ---------------------------------------------------------------------- sun disc
def toa_rgb():
    """Linear Rec.709 of the multiple-scattering model's top-of-atmosphere spectral irradiance."""
    return sky.XYZ_TO_REC709 @ (sky.MS_SUN_IRRADIANCE @ sky.MS_SPECTRAL_TO_XYZ)


def test_disc_irradiance_without_atmosphere_is_limb_darkened_sun():
    """No air, aerosols or ozone: transmittance 1 and a black sky, so the disc gives the
    top-of-atmosphere irradiance times the limb darkening's mean over the disc (0.8 exactly), times
    Cycles' float32 solid angle error (the disc's radiance is the irradiance over it)."""
    for size in (SUN_SIZE, 0.05):
        disc = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_size=size, sun_elevation=math.radians(70),
                            sun_rotation=0.3, air_density=0.0, aerosol_density=0.0, ozone_density=0.0)
        exact = 2 * math.pi * (1 - math.cos(size / 2))
        expected = 0.8 * toa_rgb() * exact / disc["solid_angle"]
        assert np.allclose(disc["irradiance"], expected, rtol=2e-4), (disc["irradiance"], expected)
    assert disc["solid_angle"] == pytest.approx(2 * math.pi * (1 - math.cos(0.025)), rel=1e-4)


def test_disc_irradiance_includes_transmittance():
    e = math.radians(30)
    clear = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=e, sun_rotation=0.0,
                         air_density=0.0, aerosol_density=0.0, ozone_density=0.0)
    disc = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=e, sun_rotation=0.0)
    normalized = (100.0 / 1000.0) / sky.MS_ATMOSPHERE_THICKNESS
    t = sky._ms_transmittance(np.array([math.sin(e)]), np.array([normalized]), 1.0, 1.0, 1.0)[0]
    rgb = sky.XYZ_TO_REC709 @ ((sky.MS_SUN_IRRADIANCE * t) @ sky.MS_SPECTRAL_TO_XYZ)
    assert np.allclose(disc["irradiance"] / clear["irradiance"], rgb / toa_rgb(), rtol=1e-3)
    assert np.all(disc["irradiance"] < 0.9 * clear["irradiance"])
    assert np.all(np.diff(disc["irradiance"]) < 0)                  # blue scattered out most

    def irradiance(**kw):
        disc = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=e, sun_rotation=0.0, **kw)
        return disc["irradiance"]

    assert np.all(irradiance(aerosol_density=3.0) < disc["irradiance"])
    assert np.all(irradiance(altitude=5000.0) > disc["irradiance"])
    assert np.all(irradiance(sun_intensity=2.0) == pytest.approx(2 * disc["irradiance"]))
    low = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(3), sun_rotation=0.0)
    assert np.all(low["irradiance"] < disc["irradiance"])


def test_disc_hidden_below_the_horizon():
    """Cycles hides the disc below the observer's horizon, which dips below the horizontal with
    altitude: at 2000 m the sun at -1 degree still shows, at -3 degrees it does not."""
    dip = sky.earth_intersection_angle(2000.0)
    assert math.degrees(dip) == pytest.approx(1.4355, abs=1e-4)
    seen = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(-1), sun_rotation=0.0,
                        altitude=2000.0)
    hidden = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=math.radians(-3), sun_rotation=0.0,
                          altitude=2000.0)
    assert seen["irradiance"][0] > 1.0
    assert np.all(hidden["irradiance"] == 0.0)
    # Cut by the horizon (at 0 seen from the ground): only the part of the disc above it shows.
    r = math.radians
    cut = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=r(0.1), sun_rotation=0.0, altitude=0.0)
    assert cut["radiance"](sky.sun_direction_from_angles(r(-0.1), 0.0)).max() == 0.0
    assert cut["radiance"](sky.sun_direction_from_angles(r(0.2), 0.0))[0, 0] > 1e4      # red: a red sun
    whole = sky.sun_disc(sky_type="MULTIPLE_SCATTERING", sun_elevation=r(0.1), sun_rotation=0.0,
                         altitude=2000.0)
    assert whole["radiance"](sky.sun_direction_from_angles(r(-0.1), 0.0))[0, 0] > 1e4


def test_disc_radiance_profile():
    """Limb darkening 1 - 0.6 (1 - sqrt(1 - r^2)) about the centre; zero outside the disc."""
    disc = sky.sun_disc(sky_type="SINGLE_SCATTERING", sun_elevation=math.radians(50), sun_rotation=1.0)
    c, half = disc["direction"], disc["angle"] / 2
    side = np.cross(c, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)                                    # horizontal: same elevation
    r = np.array([0.0, 0.5, 0.9, 0.99, 1.01])
    dirs = np.cos(r * half)[:, None] * c + np.sin(r * half)[:, None] * side
    lum = luminance(disc["radiance"](dirs))
    limb = 1 - 0.6 * (1 - np.sqrt(1 - np.minimum(r, 1) ** 2))
    assert lum[-1] == 0.0
    # The sideways points are very slightly lower than the centre (on a great circle): 1e-5.
    assert np.allclose(lum[:-1] / lum[0], limb[:-1], rtol=1e-4)


@pytest.mark.parametrize("index", range(len(CYCLES_DISC_IRRADIANCE)))
def test_disc_irradiance_from_cycles(index):
    settings, expected = CYCLES_DISC_IRRADIANCE[index]
    disc = sky.sun_disc(**settings)
    assert np.allclose(disc["irradiance"], expected, rtol=1e-3, atol=1e-3 * max(expected))
