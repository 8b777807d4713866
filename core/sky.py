"""Blender 5.0's Sky Texture node (a world's colour), evaluated as Cycles evaluates it, in NumPy.

Two parts, as in Cycles:

* the sky without the sun: ``sky_radiance(directions, ...)``.  For the two physical models
  ('MULTIPLE_SCATTERING', Blender 5.0's default, and 'SINGLE_SCATTERING', the Nishita model of
  Blender 2.90-4.x files) Cycles bakes a 512 x 256 XYZ texture once per node (columns: azimuth from
  the sun's opposite side round, the two halves mirrored; rows: elevation with a quadratic stretch
  that crowds rows at the horizon), looks it up bilinearly (Linear, Extend) for every direction,
  above or below the horizon, and converts XYZ to linear Rec.709 clamping negatives to 0.  This
  module bakes the same texture (vectorised ray marching with the same sample positions, step
  counts, look-up tables and row layout) and looks it up the same way, so that the texture's own
  discretisation is reproduced, not only the model.  Below the horizon the multiple-scattering
  texture holds the in-scattering on the way to the ground (the ground itself is black); the
  single-scattering one holds its horizon row faded by (1 - 2.5 sin(lat))^3 to black at
  sin(lat) = 0.4, lat the row's mirrored stretch.  'PREETHAM' is analytic (no texture) and uses the
  node's legacy Sun Direction vector.  'HOSEK_WILKIE' is not supported: it needs Hosek and Wilkie's
  fitted coefficient tables (3600 numbers), which this module does not carry.
* the sun disc: ``sun_disc(...)``: its direction, angular diameter, radiance per direction (two
  baked colours at the disc's lowest and highest points, interpolated linearly in elevation, times
  the limb darkening 1 - 0.6 (1 - sqrt(1 - (angle / radius)^2)) and the Sun Intensity, added to the
  sky in XYZ before the clamp) and that radiance integrated over the disc (the irradiance on a
  surface facing the sun).  The disc shows down to the observer's horizon, which dips below the
  horizontal with altitude, for both models.

Ported (reference only; behaviour checked against Blender 5.0.1 renders, tests/addon/test_sky_texture.py):

* ``intern/sky/source/sky_multiple_scattering.cpp``: ``SKY_multiple_scattering_precompute_texture``
  (4-wavelength spectral model of F. Garcia Linan: transmittance LUT 256 x 64 of 64 steps,
  in-scattering in 64 steps with the analytic multiple-scattering fit and a ground bounce),
  ``SKY_multiple_scattering_precompute_sun`` and ``SKY_earth_intersection_angle``;
* ``intern/sky/source/sky_single_scattering.cpp`` (Nishita: 21 wavelengths, 32 steps, Gauss-Laguerre
  optical depth towards the sun; the 5.0 layout with the faded lower half) and ``sky_math.h``
  (``ray_sphere_intersection``, ``sun_direction``);
* ``intern/cycles/kernel/svm/sky.h`` (``sky_radiance_nishita``, ``sky_radiance_preetham``: texture
  coordinates, the disc), ``intern/cycles/scene/shader_nodes.cpp`` (``SkyTextureNode::
  simplify_settings``: the sun angles' wrapping and the reversal of the rotation;
  ``sky_texture_precompute_nishita`` / ``_preetham``; ``get_sun_size``: the size clamped to >= 0.0005),
  ``intern/cycles/scene/image_sky.cpp`` (512 x 256, float) and ``intern/cycles/scene/shader.cpp``
  (``init_xyz_transforms``: with Blender's OCIO config the XYZ to scene-linear matrix is the
  config's CIE-XYZ D65 -> Linear Rec.709 matrix, ``XYZ_TO_REC709``).

Precision: Cycles computes in float32, this module in float64, except where float32 changes the result
measurably and is reproduced on purpose: (1) the disc's solid angle 2 pi (1 - cos(d / 2)), whose
float32 cos near 1 makes Cycles' disc 0.13 % dimmer than physical at the default size and 1.9 x
dimmer at the smallest (0.0005); (2) the distance from the observer to the ground in the
multiple-scattering bake (|o|^2 - R^2 is a difference of two numbers of ~4e7 km^2, one float32 step
being 4 km^2, and the near root -b - sqrt(b^2 - c) cancels again), which sets the radiance of every
direction below the horizon: emulated in float32, with each row's direction height sin(elevation)
correctly rounded to float32 as glibc's sinf.  Elsewhere float64 differs from Cycles by float32
rounding of the ray marching: measured 1e-4 .. 5e-4 relative (p99), up to 3e-3 at the horizon.

World directions are Blender's: Z up.  Sun Elevation and Sun Rotation are the node's (radians); with
rotation 0 the sun is towards +Y, and increasing rotation turns it towards +X.
"""
from __future__ import annotations

import math

import numpy as np

SKY_TYPES = ("MULTIPLE_SCATTERING", "SINGLE_SCATTERING", "PREETHAM", "HOSEK_WILKIE")
TEXTURE_WIDTH, TEXTURE_HEIGHT = 512, 256        # Cycles' baked sky (image_sky.cpp)
MIN_SUN_SIZE = 0.0005                           # SkyTextureNode::get_sun_size

# XYZ (D65) -> linear Rec.709: Blender 5.0's OCIO config (Linear Rec.709 from CIE-XYZ D65), which
# is what Cycles' init_xyz_transforms obtains through the aces_interchange role.
XYZ_TO_REC709 = np.array([[3.2409699, -1.5373832, -0.4986108],
                          [-0.9692436, 1.8759675, 0.0415551],
                          [0.0556301, -0.2039770, 1.0569715]])

_F32 = np.float32

# ---------------------------------------------------------------------- multiple scattering constants
MS_EARTH_RADIUS = 6371.0                        # km
MS_ATMOSPHERE_THICKNESS = 100.0                 # km
MS_ATMOSPHERE_RADIUS = MS_EARTH_RADIUS + MS_ATMOSPHERE_THICKNESS
MS_TRANSMITTANCE_STEPS = 64
MS_INSCATTERING_STEPS = 64
MS_LUT_X, MS_LUT_Y = 256, 64                    # transmittance LUT: cos(zenith) x altitude
MS_GROUND_ALBEDO = 0.3
MS_G = 0.8                                      # aerosol anisotropy
# Spectral samples at 630, 560, 490, 430 nm.
MS_SUN_IRRADIANCE = np.array([1.679, 1.828, 1.986, 1.307])
MS_MOLECULAR_SCATTERING = np.array([6.605e-3, 1.067e-2, 1.842e-2, 3.156e-2])
MS_OZONE_CROSS_SECTION = np.array([3.472e-25, 3.914e-25, 1.349e-25, 11.03e-27])
MS_OZONE_MEAN_DOBSON = 334.5
MS_AEROSOL_ABSORPTION = np.array([2.8722e-24, 4.6168e-24, 7.9706e-24, 1.3578e-23])
MS_AEROSOL_SCATTERING = np.array([1.5908e-22, 1.7711e-22, 2.0942e-22, 2.4033e-22])
MS_AEROSOL_BASE_DENSITY = 1.3681e20
MS_AEROSOL_BACKGROUND_DENSITY = 2e6
MS_AEROSOL_HEIGHT_SCALE = 0.73
MS_MULTIPLE_SCATTERING_FIT = 0.02 * np.array([0.217, 0.347, 0.594, 1.0])
MS_SPECTRAL_TO_XYZ = np.array([                 # (4 wavelengths, XYZ)
    [53.386917738564668023, 22.981337506691024754, 0.0],
    [43.904844466369358263, 71.347795700053393866, 0.102506867965741307],
    [1.6137278251608962005, 18.422960591455485011, 31.742921188390805758],
    [20.762668673810577145, 2.3614213523314368527, 110.48009643252140334]])

# ---------------------------------------------------------------------- single scattering constants
SS_RAYLEIGH_SCALE = 8e3                         # m
SS_MIE_SCALE = 1.2e3                            # m
SS_MIE_COEFF = 2e-5                             # 1/m
SS_MIE_G = 0.76
SS_EARTH_RADIUS = 6360e3                        # m
SS_ATMOSPHERE_RADIUS = 6420e3                   # m
SS_STEPS = 32
SS_STEP_LAMBDA = 20.0                           # nm between the 21 samples 380 .. 780 nm
SS_IRRADIANCE = np.array([                      # W m^-2 nm^-1 at the top of the atmosphere
    1.45756829855592995315, 1.56596305559738380175, 1.65148449067670455293, 1.71496242737209314555,
    1.75797983805020541226, 1.78256407885924539336, 1.79095108475838560302, 1.78541550133410664714,
    1.76815554864306845317, 1.74122069647250410362, 1.70647127164943679389, 1.66556087452739887134,
    1.61993437242451854274, 1.57083597368892080581, 1.51932335059305478886, 1.46628494965214395407,
    1.41245852740172450623, 1.35844961970384092709, 1.30474913844739281998, 1.25174963272610817455,
    1.19975998755420620867])
SS_RAYLEIGH_COEFF = np.array([                  # 1/m
    0.00005424820087636473, 0.00004418549866505454, 0.00003635151910165377, 0.00003017929012024763,
    0.00002526320226989157, 0.00002130859310621843, 0.00001809838025320633, 0.00001547057129129042,
    0.00001330284977336850, 0.00001150184784075764, 0.00000999557429990163, 0.00000872799973630707,
    0.00000765513700977967, 0.00000674217203751443, 0.00000596134125832052, 0.00000529034598065810,
    0.00000471115687557433, 0.00000420910481110487, 0.00000377218381260133, 0.00000339051255477280,
    0.00000305591531679811])
SS_OZONE_COEFF = np.array([                     # 1/m
    0.00000000325126849861, 0.00000000585395365047, 0.00000001977191155085, 0.00000007309568762914,
    0.00000020084561514287, 0.00000040383958096161, 0.00000063551335912363, 0.00000096707041180970,
    0.00000154797400424410, 0.00000209038647223331, 0.00000246128056164565, 0.00000273551299461512,
    0.00000215125863128643, 0.00000159051840791988, 0.00000112356197979857, 0.00000073527551487574,
    0.00000046450130357806, 0.00000033096079921048, 0.00000022512612292678, 0.00000014879129266490,
    0.00000016828623364192])
SS_CMF_XYZ = np.array([                         # CIE 1931 colour matching functions, (21, 3)
    [0.00136800000, 0.00003900000, 0.00645000100], [0.01431000000, 0.00039600000, 0.06785001000],
    [0.13438000000, 0.00400000000, 0.64560000000], [0.34828000000, 0.02300000000, 1.74706000000],
    [0.29080000000, 0.06000000000, 1.66920000000], [0.09564000000, 0.13902000000, 0.81295010000],
    [0.00490000000, 0.32300000000, 0.27200000000], [0.06327000000, 0.71000000000, 0.07824999000],
    [0.29040000000, 0.95400000000, 0.02030000000], [0.59450000000, 0.99500000000, 0.00390000000],
    [0.91630000000, 0.87000000000, 0.00165000100], [1.06220000000, 0.63100000000, 0.00080000000],
    [0.85444990000, 0.38100000000, 0.00019000000], [0.44790000000, 0.17500000000, 0.00002000000],
    [0.16490000000, 0.06100000000, 0.00000000000], [0.04677000000, 0.01700000000, 0.00000000000],
    [0.01135916000, 0.00410200000, 0.00000000000], [0.00289932700, 0.00104700000, 0.00000000000],
    [0.00069007860, 0.00024920000, 0.00000000000], [0.00016615050, 0.00006000000, 0.00000000000],
    [0.00004150994, 0.00001499000, 0.00000000000]])
# Gauss-Laguerre (n = 8) nodes scaled to end within the atmosphere, weights times exp(node).
SS_QUADRATURE_NODES = np.array([0.006811185292, 0.03614807107, 0.09004346519, 0.1706680068,
                                0.2818362161, 0.4303406404, 0.6296271457, 0.9145252695])
SS_QUADRATURE_WEIGHTS = np.array([0.01750893642, 0.04135477391, 0.06678839063, 0.09507698807,
                                  0.1283416365, 0.1707430204, 0.2327233347, 0.3562490486])


# ====================================================================== public API
class SkyTextureCache:
    """Baked sky textures by their parameters: pass one to :func:`sky_radiance` to bake once.

    An explicit object (no module state); ``textures`` maps (sky_type, sun_elevation, altitude,
    air_density, aerosol_density, ozone_density) to the (256, 512, 3) float64 XYZ texture.
    """

    def __init__(self):
        self.textures = {}

    def texture(self, sky_type, sun_elevation, altitude, air_density, aerosol_density, ozone_density):
        key = (sky_type, float(sun_elevation), float(altitude), float(air_density),
               float(aerosol_density), float(ozone_density))
        if key not in self.textures:
            self.textures[key] = bake_sky_texture(*key)
        return self.textures[key]


def cycles_sun_angles(sun_elevation, sun_rotation):
    """The node's (elevation, rotation) as Cycles' kernel uses them (``simplify_settings``).

    The elevation is wrapped into (-pi/2, pi/2) (turning the rotation by pi when it passes a
    pole), the rotation into [0, 2 pi) and then reversed: returns floats (elevation, 2 pi - rotation).
    """
    e, r = float(sun_elevation), float(sun_rotation)
    e = math.fmod(e, 2.0 * math.pi)
    if abs(e) >= math.pi:
        e -= math.copysign(2.0, e) * math.pi
    if e >= math.pi / 2 or e <= -math.pi / 2:
        e = math.copysign(math.pi, e) - e
        r += math.pi
    r = math.fmod(r, 2.0 * math.pi)
    if r < 0.0:
        r += 2.0 * math.pi
    return e, 2.0 * math.pi - r


def sun_direction_from_angles(sun_elevation, sun_rotation):
    """(3,) float64 unit vector towards the sun centre of the node's angles (radians), world Z up."""
    e, r = cycles_sun_angles(sun_elevation, sun_rotation)
    return _spherical_to_direction(e - math.pi / 2, r - math.pi / 2)


def bake_sky_texture(sky_type, sun_elevation, altitude, air_density=1.0, aerosol_density=1.0,
                     ozone_density=1.0, rows=None):
    """The XYZ texture Cycles bakes for a physical Sky Texture: (256, 512, 3) float64, row 0 the nadir.

    sky_type: 'MULTIPLE_SCATTERING' or 'SINGLE_SCATTERING'; sun_elevation in radians as Cycles'
    kernel uses it (after :func:`cycles_sun_angles`); altitude in metres.  Column u = (x + 0.5) / 512
    is the azimuth 2 pi u measured from the sun's opposite side (the sun is at u = 1/2; the two
    halves mirror each other).  Multiple scattering: row v = (y + 0.5) / 256 is the elevation
    sign(l) l^2 pi / 2 with l = 2 v - 1 (below the horizon: the in-scattering on the way to the
    ground, which itself is not seen).  Single scattering: row y >= 128 is the elevation
    (pi / 2) (y / 128 - 1)^2, and row y < 128 is the horizon row (128) times
    (1 - 2.5 sin(lat_y))^3 (0 from sin(lat_y) = 0.4), lat_y the same expression.
    rows: optional (k,) row indices to compute, the others are left NaN (a cheap band of the
    texture for look-ups near the sun).
    """
    rows = np.arange(TEXTURE_HEIGHT) if rows is None else np.unique(np.asarray(rows, np.int64))
    if sky_type == "MULTIPLE_SCATTERING":
        return _bake_multiple_scattering(sun_elevation, altitude, air_density, aerosol_density,
                                         ozone_density, rows)
    if sky_type == "SINGLE_SCATTERING":
        return _bake_single_scattering(sun_elevation, altitude, air_density, aerosol_density,
                                       ozone_density, rows)
    raise ValueError(f"no baked texture for sky type {sky_type!r}")


def sky_radiance(directions, *, sky_type="MULTIPLE_SCATTERING", sun_elevation, sun_rotation,
                 altitude=100.0, air_density=1.0, aerosol_density=1.0, ozone_density=1.0,
                 turbidity=2.2, ground_albedo=0.3, sun_direction=None, cache=None):
    """Linear Rec.709 radiance of the Sky Texture's Color output without the sun disc.

    directions : (n, 3) float64 unit world directions (Z up).
    sky_type : 'MULTIPLE_SCATTERING', 'SINGLE_SCATTERING' or 'PREETHAM' ('HOSEK_WILKIE' raises
        NotImplementedError).  Angles in radians, altitude in metres, densities and turbidity
        dimensionless, as ``bpy.types.ShaderNodeTexSky``.  ground_albedo is Hosek-Wilkie's only.
    sun_direction : Preetham only: the node's legacy Sun Direction vector (3,), which is what Cycles
        uses for that model; None derives it from sun_elevation and sun_rotation (as the disc's).
    cache : optional :class:`SkyTextureCache` reusing baked textures across calls (a bake takes
        ~2 s for multiple scattering, ~1 s for single scattering).
    Returns (n, 3) float64 linear Rec.709 radiance (W m^-2 sr^-1 as a Background of Strength 1).
    """
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    if sky_type == "PREETHAM":
        if sun_direction is None:
            sun_direction = sun_direction_from_angles(sun_elevation, sun_rotation)
        return _preetham(d, sun_direction, turbidity)
    if sky_type == "HOSEK_WILKIE":
        raise NotImplementedError("the Hosek-Wilkie sky needs its coefficient tables: not supported")
    if sky_type not in ("MULTIPLE_SCATTERING", "SINGLE_SCATTERING"):
        raise ValueError(f"unknown sky type {sky_type!r}")
    elevation, rotation = cycles_sun_angles(sun_elevation, sun_rotation)
    args = (sky_type, elevation, altitude, air_density, aerosol_density, ozone_density)
    texture = (cache or SkyTextureCache()).texture(*args)

    return _xyz_to_rgb_clamped(_sky_xyz(texture, rotation, d))


def sun_disc(*, sky_type, sun_disc=True, sun_size=0.009512044489383698, sun_intensity=1.0, sun_elevation,
             sun_rotation, altitude=100.0, air_density=1.0, aerosol_density=1.0, ozone_density=1.0,
             cache=None):
    """The sun disc Cycles adds to a physical Sky Texture, or None (no disc, or a Preetham/Hosek sky).

    Angles in radians, altitude in metres, as ``bpy.types.ShaderNodeTexSky``.  The disc's radiance
    needs the sky behind it (below): ``cache`` (a :class:`SkyTextureCache` shared with
    :func:`sky_radiance`) provides the whole baked texture; without one only the few texture rows
    around the sun are baked.  Returns a dict:

    * "direction": (3,) float64 unit vector towards the disc centre;
    * "angle": the disc's angular diameter in radians (sun_size, at least 0.0005 as in Cycles);
    * "radiance": callable (n, 3) unit directions -> (n, 3) float64 linear Rec.709 radiance that the
      disc adds to :func:`sky_radiance` (W m^-2 sr^-1, Sun Intensity included), zero outside the
      disc and below the observer's horizon (where Cycles hides it).  Cycles adds the disc's XYZ to
      the sky's and clamps negative RGB after the sum, so this is clamp(M (sky + disc)) - clamp(M sky):
      exactly what the render adds, which for a low, red sun can be slightly negative in blue (the
      disc's own colour is then outside Rec.709);
    * "irradiance": (3,) float64 W m^-2, that radiance integrated over the disc times the cosine to
      the disc's centre: what the disc gives a surface facing it.  It includes the atmosphere's
      transmittance to the sun, the limb darkening (which Cycles does not renormalise: about 0.8 of the
      top-of-atmosphere irradiance times the transmittance) and the intensity;
    * "pixel_bottom", "pixel_top": (3,) XYZ radiance Cycles bakes for the disc's lowest and highest
      points (before limb darkening and intensity); "solid_angle": the float32 solid angle (sr) the
      baked spectral irradiance is divided by.
    """
    if sky_type in ("PREETHAM", "HOSEK_WILKIE") or not sun_disc:
        return None
    if sky_type not in ("MULTIPLE_SCATTERING", "SINGLE_SCATTERING"):
        raise ValueError(f"unknown sky type {sky_type!r}")
    elevation, rotation = cycles_sun_angles(sun_elevation, sun_rotation)
    diameter = max(float(sun_size), MIN_SUN_SIZE)
    half = diameter / 2.0
    solid_angle = _solid_angle_f32(diameter)
    if sky_type == "MULTIPLE_SCATTERING":
        bottom, top = _ms_sun_pixels(elevation, half, solid_angle, altitude, air_density,
                                     aerosol_density, ozone_density)
    else:
        bottom, top = _ss_sun_pixels(elevation, half, solid_angle, altitude, air_density,
                                     aerosol_density)
    horizon = -earth_intersection_angle(altitude)
    centre = _spherical_to_direction(elevation - math.pi / 2, rotation - math.pi / 2)
    intensity = float(sun_intensity)
    key = (sky_type, elevation, altitude, air_density, aerosol_density, ozone_density)
    if cache is not None:
        texture = cache.texture(*key)
    else:   # only the rows the disc's look-ups touch
        v = _texture_v(np.sin(np.clip([elevation - half, elevation + half], -math.pi / 2, math.pi / 2)))
        y = np.floor(v * TEXTURE_HEIGHT - 0.5).astype(np.int64)
        texture = bake_sky_texture(*key, rows=np.arange(max(y[0], 0), min(y[1] + 2, TEXTURE_HEIGHT)))

    def radiance(directions):
        """(n, 3) unit directions -> (n, 3) float64 linear Rec.709 radiance the sun disc adds."""
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        out = np.zeros((len(d), 3))
        angle = _precise_angle(d, centre)
        dir_elevation = math.pi / 2 - np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        inside = np.flatnonzero((angle < half) & (dir_elevation > horizon))
        if len(inside) == 0:
            return out
        d, angle, dir_elevation = d[inside], angle[inside], dir_elevation[inside]
        y = (dir_elevation - elevation) / diameter + 0.5
        ratio = angle / half
        limb = 1.0 - 0.6 * (1.0 - np.sqrt(1.0 - ratio * ratio))
        disc = (bottom + y[:, None] * (top - bottom)) * (intensity * limb)[:, None]
        behind = _sky_xyz(texture, rotation, d)
        out[inside] = _xyz_to_rgb_clamped(behind + disc) - _xyz_to_rgb_clamped(behind)
        return out

    return {"direction": centre, "angle": diameter, "radiance": radiance,
            "irradiance": _disc_irradiance(radiance, centre, half),
            "pixel_bottom": bottom, "pixel_top": top, "solid_angle": solid_angle}


def earth_intersection_angle(altitude):
    """Angle (radians) of the horizon below the horizontal seen from ``altitude`` metres (Cycles')."""
    return math.pi / 2 - math.asin(MS_EARTH_RADIUS / (MS_EARTH_RADIUS + float(altitude) / 1000.0))


# ====================================================================== helpers
def _spherical_to_direction(theta, phi):
    return np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])


def _precise_angle(a, b):
    """Angle (n,) between unit rows of ``a`` (n, 3) and ``b`` (3,): 2 atan2(|a - b|, |a + b|)."""
    return 2.0 * np.arctan2(np.linalg.norm(a - b, axis=1), np.linalg.norm(a + b, axis=1))


def _sky_xyz(texture, rotation, d):
    """The baked ``texture`` (XYZ) at unit directions d (n, 3) as Cycles' kernel looks it up: u from
    the azimuth turned by the kernel's sun ``rotation`` (wrapped into [0, 1)), v from the elevation
    (:func:`_texture_v`), bilinear.  (n, 3) float64."""
    phi = np.arctan2(d[:, 1], d[:, 0])
    x = (-phi - math.pi / 2 + rotation) / (2.0 * math.pi)
    return _lookup_linear_extend(texture, x - np.floor(x), _texture_v(d[:, 2]))


def _xyz_to_rgb_clamped(xyz):
    return np.maximum(xyz @ XYZ_TO_REC709.T, 0.0)


def _texture_v(z):
    """Texture row coordinate (n,) of directions with height z: Cycles' inverse of the elevation
    stretch, v = 1/2 + sign(e) sqrt(|e| / (pi/2)) / 2."""
    e = math.pi / 2 - np.arccos(np.clip(z, -1.0, 1.0))
    return np.sign(e) * np.sqrt(np.abs(e) / (math.pi / 2)) * 0.5 + 0.5


def _lookup_linear_extend(texture, u, v):
    """Bilinear look-up of ``texture`` (h, w, c) at (n,) u, v in [0, 1] as Cycles' CPU images with
    Linear interpolation and Extend: texel centres at (i + 0.5) / size, indices clamped."""
    h, w = texture.shape[:2]
    x = u * w - 0.5
    y = v * h - 0.5
    ix = np.floor(x)
    iy = np.floor(y)
    tx = (x - ix)[:, None]
    ty = (y - iy)[:, None]
    ix = ix.astype(np.int64)
    iy = iy.astype(np.int64)
    x0, x1 = np.clip(ix, 0, w - 1), np.clip(ix + 1, 0, w - 1)
    y0, y1 = np.clip(iy, 0, h - 1), np.clip(iy + 1, 0, h - 1)
    return ((1 - ty) * ((1 - tx) * texture[y0, x0] + tx * texture[y0, x1])
            + ty * ((1 - tx) * texture[y1, x0] + tx * texture[y1, x1]))


def _solid_angle_f32(diameter):
    """2 pi (1 - cos(diameter / 2)) in float32, as Cycles' sun precomputation (cos near 1 is coarse)."""
    half = _F32(diameter) / _F32(2.0)
    return float(_F32(2.0 * math.pi) * (_F32(1.0) - _F32(math.cos(float(half)))))


def _ray_sphere_f32(origin_z, dirs_z, radius):
    """Blender's ray_sphere_intersection, in float32 as Cycles, for rays from (0, 0, origin_z) with
    unit directions of height dirs_z (n,) (float32 values): the far hit from inside the sphere, the
    near hit from outside, -1 for a miss.  Returns (n,) float64.

    float32 on purpose: |o|^2 - r^2 is a difference of two numbers of ~4e7 km^2 (one float32 step
    is 4 km^2) and the near hit -b - sqrt(b^2 - c) another cancellation, which together move
    Cycles' distance to the ground by up to ~0.5 % from one texture row to the next."""
    z = np.asarray(origin_z, _F32)
    b = z * np.asarray(dirs_z, _F32)
    c = _F32(z * z) - _F32(_F32(radius) * _F32(radius))
    d = b * b - c
    root = np.sqrt(np.maximum(d, _F32(0.0)))
    t = np.where(d >= b * b, -b + root, -b - root)
    return np.where(((c > 0) & (b > 0)) | (d < 0), -1.0, t.astype(np.float64))


def _disc_irradiance(radiance, centre, half, n_radial=64, n_around=256):
    """Integral of radiance(w) cos(angle to centre) over the disc of angular radius ``half``: (3,).

    Polar quadrature about the centre: angle = half sin(t) with Gauss-Legendre in t (smooth through
    the limb darkening's square root at the rim), uniform in the azimuth around the centre."""
    t, wt = np.polynomial.legendre.leggauss(n_radial)
    t = (t + 1.0) * (math.pi / 4)                       # [0, pi/2]
    wt = wt * (math.pi / 4)
    angle = half * np.sin(t)
    d_angle = half * np.cos(t) * wt                     # d(angle) weights
    psi = (np.arange(n_around) + 0.5) * (2.0 * math.pi / n_around)
    # Orthonormal frame about the centre.
    helper = np.array([1.0, 0.0, 0.0]) if abs(centre[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(centre, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(centre, e1)
    a, p = np.meshgrid(angle, psi, indexing="ij")
    dirs = (np.cos(a)[..., None] * centre + np.sin(a)[..., None]
            * (np.cos(p)[..., None] * e1 + np.sin(p)[..., None] * e2)).reshape(-1, 3)
    weight = (np.sin(angle) * np.cos(angle) * d_angle)[:, None] * np.full(n_around, 2 * math.pi / n_around)
    return (radiance(dirs) * weight.reshape(-1, 1)).sum(axis=0)


# ====================================================================== multiple scattering
def _ms_coefficients(h, air, aerosol, ozone):
    """Extinction, molecular and aerosol scattering (each (..., 4), 1/km) at altitudes h (...,) km."""
    h = h[..., None]
    molecular_scattering = MS_MOLECULAR_SCATTERING * np.exp(-0.07771971 * h ** 1.16364243) * air
    log_h = np.log(np.maximum(h, 1e-4))
    ozone_density = 3.78547397e20 * np.exp(-(log_h - 3.22261) ** 2 * 5.55555555 - log_h)
    molecular_absorption = MS_OZONE_CROSS_SECTION * MS_OZONE_MEAN_DOBSON * ozone_density * ozone
    aerosol_density = MS_AEROSOL_BASE_DENSITY * (
        np.exp(-h / MS_AEROSOL_HEIGHT_SCALE) + MS_AEROSOL_BACKGROUND_DENSITY / MS_AEROSOL_BASE_DENSITY)
    aerosol_density = aerosol_density * aerosol
    aerosol_scattering = MS_AEROSOL_SCATTERING * aerosol_density
    extinction = (MS_AEROSOL_ABSORPTION * aerosol_density + aerosol_scattering + molecular_absorption
                  + molecular_scattering)
    return extinction, molecular_scattering, aerosol_scattering


def _ms_transmittance(cos_theta, normalized_altitude, air, aerosol, ozone):
    """Transmittance (n, 4) to the sun at zenith cosines (n,) from normalized altitudes (n,)
    (0 ground .. 1 top), ray-marched in 64 steps (``get_transmittance``)."""
    cos_theta = np.asarray(cos_theta, np.float64)
    sin_theta = -np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0))     # sun_direction's x
    z0 = MS_EARTH_RADIUS + normalized_altitude * (MS_ATMOSPHERE_RADIUS - MS_EARTH_RADIUS)
    t_d = _ray_sphere_f32(z0, _F32(cos_theta), MS_ATMOSPHERE_RADIUS)
    step = t_d / MS_TRANSMITTANCE_STEPS
    depth = np.zeros(cos_theta.shape + (4,))
    for i in range(MS_TRANSMITTANCE_STEPS):
        t = (i + 0.5) * step
        x, z = sin_theta * t, z0 + cos_theta * t
        h = np.maximum(np.sqrt(x * x + z * z) - MS_EARTH_RADIUS, 0.0)
        depth += _ms_coefficients(h, air, aerosol, ozone)[0] * step[..., None]
    return np.exp(-depth)


class _TransmittanceLUT:
    """The 256 x 64 transmittance table and its look-ups (``SkyMultipleScattering``)."""

    def __init__(self, air, aerosol, ozone):
        cos_theta = np.arange(MS_LUT_X) / (MS_LUT_X - 1) * 2.0 - 1.0
        altitude = np.arange(MS_LUT_Y) / (MS_LUT_Y - 1)
        c, a = np.meshgrid(cos_theta, altitude)                         # (64, 256)
        self.lut = _ms_transmittance(c, a, air, aerosol, ozone)         # (64, 256, 4)
        self.flat = self.lut.reshape(-1, 4)
        self.ground_to_sun = self.to_sun(0.0)                           # (4,)

    def lookup(self, cos_theta, normalized_altitude):
        """Bilinear transmittance (n, 4) at zenith cosines and normalized altitudes (n,): corners by
        truncation, as ``lookup_transmittance``."""
        x = (MS_LUT_X - 1) * np.clip(cos_theta * 0.5 + 0.5, 0.0, 1.0)
        y = (MS_LUT_Y - 1) * np.clip(normalized_altitude, 0.0, 1.0)
        x1, y1 = x.astype(np.int64), y.astype(np.int64)
        dx = (x1 < MS_LUT_X - 1).astype(np.int64)                   # x2 = min(x1 + 1, last)
        dy = np.where(y1 < MS_LUT_Y - 1, MS_LUT_X, 0)
        fx, fy = (x - x1)[:, None], (y - y1)[:, None]
        flat = self.flat
        i = y1 * MS_LUT_X + x1
        a, b = flat[i], flat[i + dx]
        bottom = a + fx * (b - a)
        a, b = flat[i + dy], flat[i + dy + dx]
        top = a + fx * (b - a)
        return bottom + fy * (top - bottom)

    def at_ground(self, cos_theta):
        """Transmittance (n, 4) from the ground (row 0), linear in the zenith cosine (n,)."""
        x = (MS_LUT_X - 1) * np.clip(cos_theta * 0.5 + 0.5, 0.0, 1.0)
        x1 = x.astype(np.int64)
        x2 = np.minimum(x1 + 1, MS_LUT_X - 1)
        fx = (x - x1)[:, None]
        row = self.lut[0]
        return row[x1] + fx * (row[x2] - row[x1])

    def to_sun(self, normalized_altitude):
        """Transmittance (..., 4) towards the zenith (the last column), linear in altitude (...,)."""
        y = (MS_LUT_Y - 1) * np.clip(normalized_altitude, 0.0, 1.0)
        y1 = np.asarray(y).astype(np.int64)
        y2 = np.minimum(y1 + 1, MS_LUT_Y - 1)
        fy = np.asarray(y - y1)[..., None]
        col = self.lut[:, MS_LUT_X - 1]
        return col[y1] + fy * (col[y2] - col[y1])

    def multiscattering(self, cos_theta, normalized_altitude, distance):
        """Second-order ground bounce plus the multiple-scattering fit: (n, 4)."""
        ratio = MS_EARTH_RADIUS / distance
        omega = 2.0 * math.pi * (1.0 - np.sqrt(np.maximum(1.0 - ratio * ratio, 0.0)))
        ground_to_sample = self.ground_to_sun / self.to_sun(normalized_altitude)
        ground = ((omega / (4.0 * math.pi) * (MS_GROUND_ALBEDO / math.pi) * cos_theta)[:, None]
                  * self.at_ground(cos_theta) * ground_to_sample)
        fit = MS_MULTIPLE_SCATTERING_FIT * (1.0 / (1.0 + 5.0 * np.exp(-17.92 * cos_theta)))[:, None]
        return fit + ground


def _bake_multiple_scattering(sun_elevation, altitude, air, aerosol, ozone, rows):
    lut = _TransmittanceLUT(air, aerosol, ozone)
    altitude_km = min(max(float(altitude), 1.0), 99999.0) / 1000.0
    cos_sun = math.cos(math.pi / 2 - sun_elevation)
    sun = np.array([-math.sqrt(max(1.0 - cos_sun * cos_sun, 0.0)), 0.0, cos_sun])
    half_width = TEXTURE_WIDTH // 2
    u = (np.arange(half_width) + 0.5) / TEXTURE_WIDTH
    v = (rows + 0.5) / TEXTURE_HEIGHT
    azimuth = 2.0 * math.pi * u
    l = v * 2.0 - 1.0
    elevation = np.sign(l) * l * l * (math.pi / 2)
    el, az = np.meshgrid(elevation, azimuth, indexing="ij")               # (rows, 256)
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).reshape(-1, 3)
    z0 = MS_EARTH_RADIUS + altitude_km
    l32 = (rows.astype(_F32) + _F32(0.5)) / _F32(TEXTURE_HEIGHT) * _F32(2) - _F32(1)
    elevation32 = np.copysign(l32 * l32, l32) * _F32(math.pi / 2)
    # sinf correctly rounded (as glibc's; NumPy's float32 sin is not, off by one ulp on some rows).
    dirs_z = np.sin(elevation32.astype(np.float64)).astype(_F32).repeat(half_width)
    atmosphere = _ray_sphere_f32(z0, dirs_z, MS_ATMOSPHERE_RADIUS)
    ground = _ray_sphere_f32(z0, dirs_z, MS_EARTH_RADIUS)
    t_d = np.where(ground < 0.0, atmosphere, ground)

    # In chunks of rays: the arrays of one ray-marching step then stay in the processor's cache.
    radiance = np.concatenate([
        _ms_inscattering(lut, sun, dirs[i:i + 8192], t_d[i:i + 8192], z0, air, aerosol, ozone)
        for i in range(0, len(dirs), 8192)])
    half = (radiance @ MS_SPECTRAL_TO_XYZ).reshape(len(rows), half_width, 3)
    texture = np.full((TEXTURE_HEIGHT, TEXTURE_WIDTH, 3), np.nan)
    texture[rows] = np.concatenate([half, half[:, ::-1]], axis=1)
    return texture


def _ms_inscattering(lut, sun, dirs, t_d, z0, air, aerosol, ozone):
    """In-scattered spectral radiance (n, 4) along rays from (0, 0, z0) in unit directions dirs (n, 3)
    over distances t_d (n,) km towards the sun direction ``sun`` (3,) (``get_inscattering``: 64
    steps, energy-conserving integration of each step)."""
    cos_view = -dirs @ sun
    molecular_phase = ((3.0 / 16.0 / math.pi) * (1.0 + cos_view ** 2))[:, None]
    den = 1.0 + MS_G ** 2 + 2.0 * MS_G * cos_view
    aerosol_phase = ((1.0 - MS_G ** 2) / (4.0 * math.pi) / (den * np.sqrt(den)))[:, None]
    dt = t_d / MS_INSCATTERING_STEPS
    radiance = np.zeros((len(dirs), 4))
    transmittance = np.ones((len(dirs), 4))
    for i in range(MS_INSCATTERING_STEPS):
        t = (i + 0.5) * dt
        p = dirs * t[:, None]
        p[:, 2] += z0
        distance = np.sqrt(np.einsum("ij,ij->i", p, p))
        h = np.maximum(distance - MS_EARTH_RADIUS, 0.0)
        normalized = h / MS_ATMOSPHERE_THICKNESS
        sample_cos = (p @ sun) / distance
        extinction, molecular, aerosol_sca = _ms_coefficients(h, air, aerosol, ozone)
        to_sun = lut.lookup(sample_cos, normalized)
        ms = lut.multiscattering(sample_cos, normalized, distance)
        source = MS_SUN_IRRADIANCE * (molecular * (molecular_phase * to_sun + ms)
                                      + aerosol_sca * (aerosol_phase * to_sun + ms))
        step_transmittance = np.exp(-dt[:, None] * extinction)
        radiance += transmittance * (source - source * step_transmittance) / np.maximum(extinction, 1e-7)
        transmittance *= step_transmittance
    return radiance


def _ms_sun_pixels(elevation, half, solid_angle, altitude, air, aerosol, ozone):
    """XYZ radiance (3,), (3,) of the disc's lowest and highest points (multiple scattering)."""
    normalized = min(max(float(altitude), 1.0), 99999.0) / 1000.0 / MS_ATMOSPHERE_THICKNESS
    cos_theta = np.cos(math.pi / 2 - np.array([elevation - half, elevation + half]))
    t = _ms_transmittance(cos_theta, np.full(2, normalized), air, aerosol, ozone)
    xyz = (MS_SUN_IRRADIANCE * t / solid_angle) @ MS_SPECTRAL_TO_XYZ
    return xyz[0], xyz[1]


# ====================================================================== single scattering
def _ss_densities(h, scale):
    """Rayleigh, Mie and ozone density factors (..., 3) at heights h (...,) metres, times ``scale``."""
    return np.stack([np.exp(-h / SS_RAYLEIGH_SCALE), np.exp(-h / SS_MIE_SCALE),
                     np.maximum(0.0, 1.0 - np.abs(h - 25000.0) / 15000.0)], -1) * scale


def _ss_atmosphere_distance(pos, direction):
    """Distance (n,) from points pos (n, 3) along unit ``direction`` (n, 3) or (3,) to the top."""
    b = 2.0 * np.sum(direction * pos, axis=-1)
    c = np.sum(pos * pos, axis=-1) - SS_ATMOSPHERE_RADIUS ** 2
    return (-b + np.sqrt(np.maximum(b * b - 4.0 * c, 0.0))) / 2.0


def _ss_optical_depth(pos, direction):
    """Rayleigh, Mie, ozone optical depth factors (n, 3) from pos (n, 3) along ``direction`` (3,)."""
    length = _ss_atmosphere_distance(pos, direction)
    points = pos[:, None, :] + (SS_QUADRATURE_NODES[None, :, None] * length[:, None, None]) * direction
    h = np.linalg.norm(points, axis=-1) - SS_EARTH_RADIUS                   # (n, 8)
    depth = np.einsum("nkc,k->nc", _ss_densities(h, 1.0), SS_QUADRATURE_WEIGHTS)
    return depth * length[:, None]


def _bake_single_scattering(sun_elevation, altitude, air, aerosol, ozone, wanted):
    altitude = min(max(float(altitude), 1.0), 59999.0)
    half_width, half_height = TEXTURE_WIDTH // 2, TEXTURE_HEIGHT // 2
    origin = np.array([0.0, 0.0, SS_EARTH_RADIUS + altitude])
    sun = np.array([math.cos(sun_elevation), 0.0, math.sin(sun_elevation)])
    # Rows from the horizon (128) up are ray-marched; those below are the horizon row faded.
    rows = np.union1d(wanted[wanted >= half_height], [half_height] if wanted.min() < half_height else [])
    rows = rows.astype(np.int64)
    latitude = (math.pi / 2) * (rows / half_height - 1.0) ** 2
    longitude = (2.0 * math.pi / TEXTURE_WIDTH) * np.arange(half_width) - math.pi
    lat, lon = np.meshgrid(latitude, longitude, indexing="ij")
    dirs = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1).reshape(-1, 3)
    scale = np.array([air, aerosol, ozone], np.float64)

    length = _ss_atmosphere_distance(origin, dirs)
    segment_length = length / SS_STEPS
    segment = dirs * segment_length[:, None]
    mu = dirs @ sun
    phase_rayleigh = (0.1875 / math.pi) * (1.0 + mu * mu)
    g2 = SS_MIE_G ** 2
    phase_mie = (3.0 * (1.0 - g2) * (1.0 + mu * mu)) / (
        8.0 * math.pi * (2.0 + g2) * (1.0 + g2 - 2.0 * SS_MIE_G * mu) ** 1.5)
    optical_depth = np.zeros((len(dirs), 3))
    spectrum = np.zeros((len(dirs), len(SS_IRRADIANCE)))
    p = origin + 0.5 * segment
    for _ in range(SS_STEPS):
        h = np.linalg.norm(p, axis=1) - SS_EARTH_RADIUS
        density = _ss_densities(h, scale)
        optical_depth += segment_length[:, None] * density
        # The Earth's shadow: Blender's surface_intersection (only for a sun below the horizon; the
        # line to the sun, not the half-line, is tested).  Shadowed points add nothing.
        if sun[2] < 0.0:
            b = 2.0 * (p @ sun)
            c = np.sum(p * p, axis=1) - SS_EARTH_RADIUS ** 2
            lit = np.flatnonzero(b * b - 4.0 * c < 0.0)
        else:
            lit = np.arange(len(dirs))
        total = optical_depth[lit] + _ss_optical_depth(p[lit], sun) * scale
        extinction = (total[:, 0:1] * SS_RAYLEIGH_COEFF + total[:, 1:2] * (1.11 * SS_MIE_COEFF)
                      + total[:, 2:3] * SS_OZONE_COEFF)
        scattering = (phase_rayleigh[lit] * density[lit, 0])[:, None] * SS_RAYLEIGH_COEFF + (
            phase_mie[lit] * density[lit, 1] * SS_MIE_COEFF)[:, None]
        spectrum[lit] += np.exp(-extinction) * scattering * SS_IRRADIANCE * segment_length[lit, None]
        p = p + segment
    xyz = (spectrum @ SS_CMF_XYZ) * SS_STEP_LAMBDA
    half = xyz.reshape(len(rows), half_width, 3)
    texture = np.full((TEXTURE_HEIGHT, TEXTURE_WIDTH, 3), np.nan)
    texture[rows] = np.concatenate([half, half[:, ::-1]], axis=1)
    # Below the horizon: the horizon row faded out, (1 - 2.5 sin(lat))^3 down to sin(lat) = 0.4,
    # with lat the row's own (mirrored) stretch.
    below = wanted[wanted < half_height]
    sin_lat = np.sin((math.pi / 2) * (below / half_height - 1.0) ** 2)
    fade = np.where(sin_lat < 0.4, (1.0 - 2.5 * sin_lat) ** 3, 0.0)
    texture[below] = texture[half_height] * fade[:, None, None]
    return texture


def _ss_sun_pixels(elevation, half, solid_angle, altitude, air, aerosol):
    """XYZ radiance (3,), (3,) of the disc's lowest and highest points (single scattering): black
    when the whole disc is below the horizon, elevations clamped to >= 0."""
    altitude = min(max(float(altitude), 1.0), 59999.0)
    bottom, top = max(elevation - half, 0.0), max(elevation + half, 0.0)
    if top <= 0.0:
        return np.zeros(3), np.zeros(3)
    e = np.array([bottom, top])
    dirs = np.stack([np.cos(e), np.zeros(2), np.sin(e)], -1)
    origin = np.array([[0.0, 0.0, SS_EARTH_RADIUS + altitude]])
    depth = np.stack([_ss_optical_depth(origin, d)[0] for d in dirs])       # (2, 3)
    tau = (np.outer(depth[:, 0] * air, SS_RAYLEIGH_COEFF)
           + np.outer(depth[:, 1] * aerosol, np.full(len(SS_IRRADIANCE), 1.11 * SS_MIE_COEFF)))
    spectrum = SS_IRRADIANCE * np.exp(-tau) / solid_angle
    xyz = (spectrum @ SS_CMF_XYZ) * SS_STEP_LAMBDA
    return xyz[0], xyz[1]


# ====================================================================== Preetham
def _perez(lam, theta, gamma):
    return (1.0 + lam[0] * np.exp(lam[1] / np.cos(theta))) * (
        1.0 + lam[2] * np.exp(lam[3] * gamma) + lam[4] * np.cos(gamma) ** 2)


def _preetham(d, sun, turbidity):
    """Cycles' Preetham sky (n, 3) for unit directions d (n, 3) and the Sun Direction ``sun`` (3,)."""
    sun = np.asarray(sun, np.float64)
    sun = sun / np.linalg.norm(sun)
    theta_s = math.acos(min(max(sun[2], -1.0), 1.0))
    phi_s = math.atan2(sun[0], sun[1])
    t = float(turbidity)
    t2 = t * t
    th2, th3 = theta_s ** 2, theta_s ** 3
    chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * theta_s)
    zenith_Y = ((4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192) * 0.06
    zenith_x = ((0.00166 * th3 - 0.00375 * th2 + 0.00209 * theta_s) * t2
                + (-0.02903 * th3 + 0.06377 * th2 - 0.03202 * theta_s + 0.00394) * t
                + (0.11693 * th3 - 0.21196 * th2 + 0.06052 * theta_s + 0.25886))
    zenith_y = ((0.00275 * th3 - 0.00610 * th2 + 0.00317 * theta_s) * t2
                + (-0.04214 * th3 + 0.08970 * th2 - 0.04153 * theta_s + 0.00516) * t
                + (0.15346 * th3 - 0.26756 * th2 + 0.06670 * theta_s + 0.26688))
    perez_Y = [0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251, 0.1206 * t - 2.5771,
               -0.0670 * t + 0.3703]
    perez_x = [-0.0193 * t - 0.2592, -0.0665 * t + 0.0008, -0.0004 * t + 0.2125, -0.0641 * t - 0.8989,
               -0.0033 * t + 0.0452]
    perez_y = [-0.0167 * t - 0.2608, -0.0950 * t + 0.0092, -0.0079 * t + 0.2102, -0.0441 * t - 1.6537,
               -0.0109 * t + 0.0529]
    zenith_Y /= _perez(perez_Y, 0.0, theta_s)
    zenith_x /= _perez(perez_x, 0.0, theta_s)
    zenith_y /= _perez(perez_y, 0.0, theta_s)

    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = -np.arctan2(d[:, 1], d[:, 0]) + math.pi / 2
    cos_gamma = np.sin(theta) * math.sin(theta_s) * np.cos(phi_s - phi) + np.cos(theta) * math.cos(theta_s)
    gamma = np.arccos(np.clip(cos_gamma, -1.0, 1.0))
    theta = np.minimum(theta, math.pi / 2 - 0.001)
    x = zenith_x * _perez(perez_x, theta, gamma)
    y = zenith_y * _perez(perez_y, theta, gamma)
    Y = zenith_Y * _perez(perez_Y, theta, gamma)
    safe_y = np.where(y != 0.0, y, 1.0)
    X = np.where(y != 0.0, x / safe_y * Y, 0.0)
    Z = np.where((y != 0.0) & (Y != 0.0), (1.0 - x - y) / safe_y * Y, 0.0)
    return _xyz_to_rgb_clamped(np.stack([X, Y, Z], -1))
