"""core/pattern_textures.py (Wave, Brick, Magic, White Noise): properties and values Cycles rendered.

The values in CYCLES and WHITE were read from Cycles' renders of tests/addon/test_pattern_textures_cycles.py
(Blender 5.0.1, float32 EXR, 64 x 64 plane) at four pixel centres each; the points are the float32
coordinates Cycles formed there.  Cycles computes in float32, hence the 1e-4 tolerance (measured
differences <= 3e-5, most < 1e-6); white noise hashes the float32 bits, so it must agree exactly.
"""
from __future__ import annotations

import numpy as np
import pytest

from core.pattern_textures import (BANDS_DIRECTIONS, RINGS_DIRECTIONS, WAVE_PROFILES, brick_noise,
                                   brick_texture, magic_texture, wave_texture, white_noise_texture)

TOL = 1e-4
PLANE = [(-0.4556249976158142, 0.6581249833106995, 0.4300000071525574),
         (0.6068750023841858, 0.18937499821186066, 0.4300000071525574),
         (-0.2993749976158142, -0.34187501668930054, 0.4300000071525574),
         (1.200624942779541, -0.9981250166893005, 0.4300000071525574)]
COLORS = dict(color1=(0.9, 0.3, 0.1), color2=(0.1, 0.5, 0.8), mortar=(0.2, 0.25, 0.15))
DISTORT = dict(distortion=3.0, detail=2.5, detail_scale=1.3, detail_roughness=0.6)
# (case, function, keyword arguments, points, Cycles' Color at the points)
CYCLES = [
    ("wave_bands_diagonal_sin_distorted", wave_texture,
     dict(bands_direction="DIAGONAL", scale=1.5, **DISTORT), PLANE,
     [0.9848648309707642, 0.4412771165370941, 0.9404383897781372, 0.944475531578064]),
    ("wave_rings_spherical_saw_distorted", wave_texture,
     dict(wave_type="RINGS", rings_direction="SPHERICAL", wave_profile="SAW", scale=1.5,
          **{**DISTORT, "detail": 3.0}),
     PLANE, [0.3650503158569336, 0.5125253200531006, 0.9052374362945557, 0.7931170463562012]),
    ("wave_rings_x_sin", wave_texture, dict(wave_type="RINGS", rings_direction="X", scale=1.5),
     [(0.3100000023841858, -0.9356250166893005, 1.2581250667572021),
      (0.3100000023841858, 0.12687499821186066, 0.7893750071525574),
      (0.3100000023841858, -0.7793750166893005, 0.2581250071525574),
      (0.3100000023841858, 0.7206249833106995, -0.3981249928474426)],
     [0.9980958700180054, 0.2946416139602661, 0.06182098388671875, 0.046376556158065796]),
    ("brick_offset_squash_bias", brick_texture,
     dict(offset=0.3, offset_frequency=3, squash=0.6, squash_frequency=2, scale=1.5, mortar_size=0.04,
          mortar_smooth=0.0, bias=0.2, **COLORS),
     [(-0.5806249976158142, 0.8143749833106995, 0.4300000071525574),      # mortar
      (0.4506250023841858, 0.7831249833106995, 0.4300000071525574),
      (-0.2368749976158142, 0.7831249833106995, 0.4300000071525574),
      (-0.6118749976158142, 0.12687499821186066, 0.4300000071525574)],    # tint clamped to 1
     [(0.20000000298023224, 0.25, 0.15000000596046448),
      (0.1871425211429596, 0.4782143831253052, 0.7237502932548523),
      (0.1822044849395752, 0.4794488847255707, 0.7280710935592651),
      (0.10000000149011612, 0.5, 0.800000011920929)]),
    ("brick_smooth_negative_bias", brick_texture,
     dict(offset_frequency=1, scale=1.5, mortar_size=0.08, mortar_smooth=0.4, bias=-0.2, **COLORS),
     [(-0.5806249976158142, 0.8143749833106995, 0.4300000071525574),
      (-0.4556249976158142, 0.7831249833106995, 0.4300000071525574),      # on the smooth ramp
      (-0.2368749976158142, 0.7518749833106995, 0.4300000071525574),
      (1.106874942779541, -0.43562501668930054, 0.4300000071525574)],
     [(0.20000000298023224, 0.25, 0.15000000596046448),
      (0.3248218297958374, 0.35809141397476196, 0.3890230655670166),
      (0.4016191363334656, 0.4245952069759369, 0.5360832810401917),
      (0.5285879373550415, 0.3928530216217041, 0.42498552799224854)]),
    ("magic_depth10_distortion0.7", magic_texture, dict(depth=10, distortion=0.7), PLANE,
     [(0.9596496820449829, 0.32720625400543213, 0.702161431312561),
      (0.9318993091583252, 0.43493473529815674, 0.6217324137687683),
      (0.9896228313446045, 0.35820430517196655, 0.6158770322799683),
      (0.9490334987640381, 0.3124069571495056, 0.7162616848945618)]),
    ("magic_depth4_distortion2.5", magic_texture, dict(depth=4, distortion=2.5, scale=3.0), PLANE,
     [(0.07621195912361145, 0.1498563587665558, 0.47336524724960327),
      (0.16929757595062256, 0.7913506031036377, 0.9903666973114014),
      (0.0166531503200531, 0.8910036087036133, 0.6861405372619629),
      (0.9521652460098267, 0.05833449959754944, 0.0008502304553985596)]),
    ("magic_depth3_fmod", magic_texture, dict(depth=3),            # coordinates beyond +-2 pi
     [(5.234375, -5.671875, 0.4300000071525574), (6.296875, -6.140625, 0.4300000071525574),
      (5.390625, -6.671875, 0.4300000071525574), (6.890625, -7.328125, 0.4300000071525574)],
     [(0.004952341318130493, 0.9998964071273804, 0.905117928981781),
      (0.94563889503479, 0.9778570532798767, 0.2835807502269745),
      (0.04926943778991699, 0.8690194487571716, 0.40167036652565),
      (0.0848906934261322, 0.7746791839599609, 0.9720925688743591)]),
]
# White noise: W = x for 1D, 0.37 for 4D; Cycles' Color at WHITE_POINTS.
WHITE_POINTS = [(-0.46875, 0.65625, 0.40625), (0.59375, 0.1875, 0.40625), (-0.3125, -0.34375, 0.40625),
                (1.1875, -1.0, 0.40625)]
WHITE = {
    "1D": [(0.2482624650001526, 0.07111968845129013, 0.013448869809508324),
           (0.3175632059574127, 0.6062819361686707, 0.8689262866973877),
           (0.151969775557518, 0.01295819878578186, 0.4900074303150177),
           (0.30986958742141724, 0.5641969442367554, 0.545523464679718)],
    "2D": [(0.9644241333007812, 0.3223504424095154, 0.38801872730255127),
           (0.8809902667999268, 0.19535599648952484, 0.15428675711154938),
           (0.3976951837539673, 0.9121162295341492, 0.8561472296714783),
           (0.18665878474712372, 0.8871623873710632, 0.3236525356769562)],
    "3D": [(0.6106569170951843, 0.10956362634897232, 0.4796914756298065),
           (0.8070163130760193, 0.9148576855659485, 0.3714331090450287),
           (0.2100861817598343, 0.890690803527832, 0.37715592980384827),
           (0.47779518365859985, 0.8702400326728821, 0.9598431587219238)],
    "4D": [(0.06577344238758087, 0.9078097343444824, 0.18615972995758057),
           (0.10878430306911469, 0.7680848240852356, 0.6337997913360596),
           (0.2843226194381714, 0.8233854174613953, 0.12831655144691467),
           (0.4938868582248688, 0.35358530282974243, 0.3882506787776947)],
}


def random_points(n=3000, seed=0, spread=3.0):
    return np.random.default_rng(seed).uniform(-spread, spread, (n, 3))


def _white_w(dimensions, vector):
    return vector[:, 0] if dimensions == "1D" else 0.37


# ---------------------------------------------------------------------------------- values from Cycles
@pytest.mark.parametrize("name, function, kwargs, points, expected", CYCLES, ids=[c[0] for c in CYCLES])
def test_values_rendered_by_cycles(name, function, kwargs, points, expected):
    out = function(np.array(points), **kwargs)
    expected = np.array(expected)
    if expected.ndim == 1:                   # grey
        expected = np.repeat(expected[:, None], 3, axis=1)
    np.testing.assert_allclose(out["Color"], expected, atol=TOL, rtol=0)


@pytest.mark.parametrize("dimensions", list(WHITE))
def test_white_noise_values_rendered_by_cycles_exactly(dimensions):
    vector = np.array(WHITE_POINTS)
    out = white_noise_texture(vector, dimensions=dimensions, w=_white_w(dimensions, vector))
    np.testing.assert_array_equal(out["Color"], np.array(WHITE[dimensions]))
    np.testing.assert_array_equal(out["Value"], out["Color"][:, 0])


# ---------------------------------------------------------------------------------- all nodes
NODES = [
    (wave_texture, dict(distortion=2.0, detail=2.5)),
    (brick_texture, dict(mortar_smooth=0.3, **COLORS)),
    (magic_texture, dict(depth=5)),
    (white_noise_texture, dict(dimensions="4D", w=0.5)),
]


@pytest.mark.parametrize("function, kwargs", NODES, ids=[f[0].__name__ for f in NODES])
def test_shapes_dtypes_deterministic_and_pointwise(function, kwargs):
    p = random_points()
    out = function(p, **kwargs)
    again = function(p.copy(), **kwargs)
    halves = [function(p[:1234], **kwargs), function(p[1234:], **kwargs)]
    for key, value in out.items():
        assert value.dtype == np.float64 and value.shape in {(len(p),), (len(p), 3)}
        assert np.all(np.isfinite(value))
        np.testing.assert_array_equal(value, again[key])
        np.testing.assert_array_equal(value, np.concatenate([h[key] for h in halves]))


def test_unknown_settings_raise():
    p = random_points(5)
    with pytest.raises(ValueError):
        wave_texture(p, wave_type="SPIRAL")
    with pytest.raises(ValueError):
        wave_texture(p, wave_profile="SQUARE")
    with pytest.raises(ValueError):
        white_noise_texture(p, dimensions="5D")
    with pytest.raises(ValueError):
        magic_texture(p, depth=-1)
    with pytest.raises(ValueError):
        magic_texture(p[:, :2])


# ---------------------------------------------------------------------------------- wave
@pytest.mark.parametrize("profile", WAVE_PROFILES)
@pytest.mark.parametrize("distortion", [0.0, 4.0])
def test_wave_in_unit_interval_and_grey(profile, distortion):
    out = wave_texture(random_points(), wave_profile=profile, distortion=distortion, detail=3.5)
    assert out["Fac"].min() >= 0.0 and out["Fac"].max() <= 1.0
    assert np.ptp(out["Fac"]) > 0.9
    np.testing.assert_array_equal(out["Color"], np.repeat(out["Fac"][:, None], 3, axis=1))


@pytest.mark.parametrize("direction", BANDS_DIRECTIONS)
@pytest.mark.parametrize("profile", ["SIN", "SAW"])
def test_wave_bands_periodic_along_their_direction(direction, profile):
    """Bands repeat every 2 pi / (20 scale) (diagonal: the sum of coordinates, every 2 pi / (10 scale)),
    up to the kernel's 0.999999 nudge, and are constant across their direction."""
    scale = 1.7
    p = random_points(500)
    axis = np.ones(3) if direction == "DIAGONAL" else np.eye(3)["XYZ".index(direction)]
    period = 2 * np.pi / (scale * (10.0 if direction == "DIAGONAL" else 20.0) * np.float32(0.999999))
    f = wave_texture(p, bands_direction=direction, wave_profile=profile, scale=scale)["Fac"]
    shifted = wave_texture(p + 3 * period * axis / (3.0 if direction == "DIAGONAL" else 1.0),
                           bands_direction=direction, wave_profile=profile, scale=scale)["Fac"]
    across = np.array([1.0, -1.0, 0.0]) if direction in ("Z", "DIAGONAL") else np.array([0.0, 0.0, 1.0])
    moved = wave_texture(p + 0.37 * across, bands_direction=direction, wave_profile=profile,
                         scale=scale)["Fac"]
    keep = np.abs(f - 0.5) < 0.49                 # away from the saw's wrap
    np.testing.assert_allclose(shifted[keep], f[keep], atol=1e-5)
    np.testing.assert_allclose(moved[keep], f[keep], atol=1e-5)


@pytest.mark.parametrize("direction", RINGS_DIRECTIONS)
def test_wave_rings_depend_on_the_distance_to_their_axis(direction):
    p = random_points(500)
    rotated = p.copy()
    if direction == "SPHERICAL":
        rotated = p[:, [1, 2, 0]]                       # same length
    else:
        k = "XYZ".index(direction)
        i, j = [a for a in range(3) if a != k]
        rotated[:, i], rotated[:, j] = -p[:, j], p[:, i]  # a quarter turn about the axis
        rotated[:, k] += 1.234                            # moving along the axis changes nothing
    f = wave_texture(p, wave_type="RINGS", rings_direction=direction, scale=2.0)["Fac"]
    g = wave_texture(rotated, wave_type="RINGS", rings_direction=direction, scale=2.0)["Fac"]
    np.testing.assert_allclose(g, f, atol=1e-4)         # the 1e-6 nudge moves the centre slightly


def test_wave_profiles_are_one_phase():
    """TRI = 2 min(SAW, 1 - SAW); SIN = (1 - cos(2 pi SAW)) / 2 (up to float32's pi / 2 and 2 pi: 1e-5);
    a phase of 2 pi changes nothing."""
    p = random_points()
    kw = dict(distortion=1.5, detail=1.5, phase_offset=0.4)
    saw = wave_texture(p, wave_profile="SAW", **kw)["Fac"]
    tri = wave_texture(p, wave_profile="TRI", **kw)["Fac"]
    sin = wave_texture(p, wave_profile="SIN", **kw)["Fac"]
    np.testing.assert_allclose(tri, 2 * np.minimum(saw, 1 - saw), atol=1e-6)
    np.testing.assert_allclose(sin, 0.5 - 0.5 * np.cos(2 * np.pi * saw), atol=1e-5)
    turned = wave_texture(p, wave_profile="SIN", **{**kw, "phase_offset": 0.4 + 2 * np.pi})["Fac"]
    np.testing.assert_allclose(turned, sin, atol=1e-5)


def test_wave_distortion_depends_on_detail_scale_and_not_when_zero():
    p = random_points(500)
    plain = wave_texture(p)["Fac"]
    np.testing.assert_array_equal(wave_texture(p, detail=7.0, detail_scale=3.0)["Fac"], plain)
    a = wave_texture(p, distortion=2.0, detail_scale=1.0)["Fac"]
    b = wave_texture(p, distortion=2.0, detail_scale=2.0)["Fac"]
    assert np.abs(a - plain).max() > 0.1 and np.abs(a - b).max() > 0.1


# ---------------------------------------------------------------------------------- brick
def test_brick_noise_is_cycles_integer_hash():
    """Python-int arithmetic modulo 2**32 of the C code gives the same values, negative keys included."""
    keys = [0, 1, 2, 65535, 65536, 123456789, -1, -65536 + 7, 2**31 - 1]

    def reference(n):
        n = ((n & 0xFFFFFFFF) + 1013) & 0x7FFFFFFF
        n = (n >> 13) ^ n
        nn = (n * ((n * n * 60493 + 19990303) & 0xFFFFFFFF) + 1376312589) & 0x7FFFFFFF
        return 0.5 * float(np.float32(np.float32(nn) / np.float32(2.0 ** 30)))

    got = brick_noise(np.array(keys))
    np.testing.assert_array_equal(got, [reference(k) for k in keys])
    assert got.min() >= 0.0 and got.max() <= 1.0


def _brick_grid(frac=(0.5, 0.5), rows=range(-3, 3), bricks=range(-4, 4)):
    """Points (n, 3) at fractions ``frac`` of the bricks (width 0.5, rows 0.25, scale 1) with the
    default offset (every other row, row 0 included, shifted by half a brick width)."""
    r, b = np.meshgrid(list(rows), list(bricks), indexing="ij")
    r, b = r.ravel(), b.ravel()
    shift = np.where(r % 2 == 0, 0.25, 0.0)
    return np.stack([(b + frac[0]) * 0.5 - shift, (r + frac[1]) * 0.25, np.zeros(r.size)], axis=1)


def test_brick_constant_within_a_brick_away_from_mortar():
    kw = dict(scale=1.0, mortar_size=0.02, **COLORS)
    base = brick_texture(_brick_grid(), **kw)
    assert np.all(base["Fac"] == 0.0)
    assert len(np.unique(base["Color"].round(9), axis=0)) > 20          # the tint varies between bricks
    for frac in [(0.1, 0.2), (0.9, 0.85), (0.5, 0.1), (0.05, 0.9)]:
        other = brick_texture(_brick_grid(frac), **kw)
        assert np.all(other["Fac"] == 0.0)
        np.testing.assert_allclose(other["Color"], base["Color"], atol=1e-12)


def test_brick_mortar_and_color_mix():
    kw = dict(scale=1.0, offset_frequency=2, squash=1.0, mortar_size=0.05, **COLORS)
    # points near a row's bottom edge (y = row * 0.25 + 0.01)
    pts = _brick_grid(frac=(0.5, 0.04))
    hard = brick_texture(pts, mortar_smooth=0.0, **kw)
    assert np.all(hard["Fac"] == 1.0)
    np.testing.assert_array_equal(hard["Color"], np.broadcast_to(COLORS["mortar"], pts.shape))
    smooth = brick_texture(pts, mortar_smooth=1.0, **kw)
    # min_dist = 0.01 of mortar 0.05: smoothstep(1 - 0.2) = 3 0.8^2 - 2 0.8^3
    np.testing.assert_allclose(smooth["Fac"], 3 * 0.64 - 2 * 0.512, atol=1e-6)
    # bricks are between color1 and color2 (tint in [0, 1]); Fac 0 inside
    inside = brick_texture(_brick_grid(), bias=0.3, **kw)
    c1, c2 = np.array(COLORS["color1"]), np.array(COLORS["color2"])
    t = (inside["Color"][:, 0] - c1[0]) / (c2[0] - c1[0])
    assert t.min() >= 0.3 - 1e-6 and t.max() <= 1.0 + 1e-6 and np.mean(t == 1.0) > 0.1   # clamped
    np.testing.assert_allclose(inside["Color"], c1 + t[:, None] * (c2 - c1), atol=1e-6)
    # per-point colours (n, 3) are used point by point
    per_point = brick_texture(_brick_grid(), bias=0.3, **{**kw, "color1": np.tile(c1, (48, 1))})
    np.testing.assert_allclose(per_point["Color"], inside["Color"], atol=1e-12)


def test_brick_offset_and_squash_rows():
    """Every offset_frequency-th row (row 0 included) shifts by width * offset; every
    squash_frequency-th row has bricks of width * squash (its shift uses the squashed width)."""
    kw = dict(scale=1.0, mortar_size=0.01, mortar_smooth=0.0, **COLORS)
    y = np.array([0.125, 0.375, 0.625, 0.875])                # rows 0..3
    x = np.linspace(-1.0, 1.0, 4001)
    pts = np.stack([np.repeat(x[None], 4, 0), np.repeat(y[:, None], len(x), 1), np.zeros((4, len(x)))], -1)
    fac = brick_texture(pts.reshape(-1, 3), offset=0.3, offset_frequency=2, squash=0.6, squash_frequency=3,
                        **kw)["Fac"].reshape(4, -1)
    for row in range(4):
        width = 0.5 * (0.6 if row % 3 == 0 else 1.0)
        shift = width * 0.3 if row % 2 == 0 else 0.0
        edges = np.arange(-6, 6) * width - shift                # the bricks' vertical edges
        near = np.abs(x[:, None] - edges[None]).min(axis=1)
        assert np.all(fac[row][near < 0.009] == 1.0) and np.all(fac[row][near > 0.011] == 0.0), row


# ---------------------------------------------------------------------------------- magic
def test_magic_depth_zero_closed_form_and_fac_is_mean():
    p = random_points()
    for distortion, div in [(0.0, 1.0), (1.3, 2.6)]:
        out = magic_texture(p, depth=0, scale=2.0, distortion=distortion)
        q = np.fmod(p, np.float32(2 * np.pi))
        a = 10.0 * np.stack([q.sum(1), -q[:, 0] + q[:, 1] - q[:, 2], -q[:, 0] - q[:, 1] + q[:, 2]], 1)
        expected = 0.5 - np.stack([np.sin(a[:, 0]), np.cos(a[:, 1]), -np.cos(a[:, 2])], 1) / div
        np.testing.assert_allclose(out["Color"], expected, atol=1e-7)
        np.testing.assert_allclose(out["Fac"], out["Color"].mean(1), atol=1e-15)


def test_magic_depth_range_and_fmod():
    p = random_points(spread=2.0)
    deep = [magic_texture(p, depth=d, distortion=1.7)["Color"] for d in range(12)]
    for d in range(1, 11):
        assert np.abs(deep[d] - deep[d - 1]).max() > 0.05, d      # every level changes the colour
    np.testing.assert_array_equal(deep[11], deep[10])            # Cycles stops at depth 10
    for color in deep:                                           # |x| <= distortion: in [0, 1]
        assert color.min() >= -1e-12 and color.max() <= 1.0 + 1e-12
    # coordinates are reduced modulo 2 pi (float32's) before the scale applies
    q = np.abs(p) % 6.0
    two_pi = float(np.float32(2 * np.pi))
    np.testing.assert_allclose(magic_texture(q + two_pi, depth=3)["Color"],
                               magic_texture(q, depth=3)["Color"], atol=1e-9)


# ---------------------------------------------------------------------------------- white noise
@pytest.mark.parametrize("dimensions", ["1D", "2D", "3D", "4D"])
def test_white_noise_range_and_inputs_used(dimensions):
    p = random_points()
    w = _white_w(dimensions, p)
    out = white_noise_texture(p, dimensions=dimensions, w=w)
    assert out["Value"].min() >= 0.0 and out["Value"].max() <= 1.0
    assert abs(out["Value"].mean() - 0.5) < 0.03 and abs(out["Color"].mean() - 0.5) < 0.03
    np.testing.assert_array_equal(out["Value"], out["Color"][:, 0])
    used = {"1D": [], "2D": [0, 1], "3D": [0, 1, 2], "4D": [0, 1, 2]}[dimensions]
    for axis in range(3):
        moved = p.copy()
        moved[:, axis] += 0.25
        again = white_noise_texture(moved, dimensions=dimensions, w=w)["Value"]
        if axis in used:
            assert np.mean(again == out["Value"]) < 0.01
        else:
            np.testing.assert_array_equal(again, out["Value"])


def test_white_noise_keys_are_float32():
    """Coordinates rounding to the same float32 hash alike; the next float32 hashes differently."""
    p = np.array(WHITE_POINTS)
    same = p + 1e-12
    nxt = np.nextafter(p.astype(np.float32), np.float32(np.inf)).astype(np.float64)
    base = white_noise_texture(p)["Color"]
    np.testing.assert_array_equal(white_noise_texture(same)["Color"], base)
    assert np.all(white_noise_texture(nxt)["Color"] != base)


def test_a_wave_of_a_million_octaves_takes_the_most_it_can_use():
    """A driver's Detail of 1e6 (Blender's socket stops at 15) takes ``MAX_WAVE_DETAIL`` octaves,
    finite, where each octave was a Python step: the export stalled for minutes (found by a fuzz
    sweep)."""
    from core.pattern_textures import MAX_WAVE_DETAIL
    p = random_points()
    huge = wave_texture(p, distortion=1.0, detail=1e6, detail_roughness=1.0)
    most = wave_texture(p, distortion=1.0, detail=MAX_WAVE_DETAIL, detail_roughness=1.0)
    assert np.isfinite(huge["Fac"]).all()
    np.testing.assert_array_equal(huge["Fac"], most["Fac"])
    fewer = wave_texture(p, distortion=1.0, detail=2.0, detail_roughness=1.0)
    assert not np.array_equal(most["Fac"], fewer["Fac"])


def test_extreme_inputs_give_cycles_int_min_cells_without_warnings():
    """A Scale of 1e30 and a Row Height or Brick Width of 0 make cells beyond int32 (or NaN): they
    become INT_MIN as Cycles' float_to_int on x86 makes them, finite and without NumPy's cast
    warning (pytest makes it an error; before stop 76, "invalid value encountered in cast"), as
    the Checker's and Voronoi's cells."""
    from core.texture_hash import float_to_int
    from core.voronoi import voronoi_texture
    assert float_to_int(np.array([3.0, -2.0 ** 31, 2.0 ** 31, np.inf, -np.inf, np.nan])).tolist() == \
        [3, -2 ** 31, -2 ** 31, -2 ** 31, -2 ** 31, -2 ** 31]
    v = np.array([[0.3, 0.4, 0.0], [1.0, 2.0, 0.0], [-1e30, 1e30, 0.0]])
    for kw in ({"scale": 1e30}, {"row_height": 0.0}, {"brick_width": 0.0}, {"row_height": 1e-30}):
        out = brick_texture(v, color1=(1, 0, 0), color2=(0, 1, 0), mortar=(0, 0, 0), **kw)
        assert np.isfinite(out["Color"]).all() and np.isfinite(out["Fac"]).all(), kw
    cells = voronoi_texture(v, 1e30)
    assert all(np.isfinite(x).all() for x in cells.values() if isinstance(x, np.ndarray))

