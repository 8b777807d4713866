"""core.noise (Cycles' Noise Texture port) and core.texture_hash: properties and values from Cycles.

The values in CYCLES were rendered by Blender 5.0's Cycles (tests/addon/test_noise_texture.py's
cases, Color output, float32); the port computes in float64, hence the 5e-4 tolerance (the addon test
measures differences of at most ~2e-4 on these settings).
"""
from __future__ import annotations

import numpy as np
import pytest

from core import texture_hash as th
from core.noise import NOISE_TYPES, noise, noise_select, noise_texture, perlin, snoise

BASE = dict(scale=5.0, detail=2.5, roughness=0.6, lacunarity=2.3)
POINTS = np.array([(-0.6691666666666667, 0.8091666666666666, 0.43),
                   (-0.29416666666666674, 0.1425, 0.43),
                   (-0.16916666666666663, -0.48250000000000004, 0.43),
                   (1.2891666666666668, -1.1491666666666667, 0.43)])
CYCLES = {
    "fbm_distorted": (dict(distortion=0.7), [
        (0.4894465208053589, 0.33348238468170166, 0.5542418956756592),
        (0.4141656160354614, 0.5643665790557861, 0.7232421040534973),
        (0.3276962637901306, 0.5769332051277161, 0.4861431121826172),
        (0.4934889078140259, 0.49001938104629517, 0.522004246711731)]),
    "hybrid": (dict(distortion=0.0, noise_type="HYBRID_MULTIFRACTAL", offset=0.8, gain=1.5), [
        (1.9398744106292725, 1.2821985483169556, 2.032925605773926),
        (0.722019374370575, 1.7032681703567505, 1.87448251247406),
        (1.4547752141952515, 1.2991381883621216, 1.5658625364303589),
        (1.6203956604003906, 1.5059772729873657, 1.6004137992858887)]),
    "fbm_4d": (dict(distortion=0.7, dimensions="4D", w=0.37), [
        (0.5396898984909058, 0.46418261528015137, 0.4467507004737854),
        (0.39679044485092163, 0.6244025230407715, 0.4218715727329254),
        (0.4915078580379486, 0.49464553594589233, 0.3894833028316498),
        (0.5100017189979553, 0.5938169360160828, 0.5637418627738953)]),
    "hybrid_cutoff": (dict(distortion=0.0, noise_type="HYBRID_MULTIFRACTAL", detail=4.5), [
        (-0.024939242750406265, -0.24473322927951813, -0.09049924463033676),
        (-0.4309864342212677, -0.056967101991176605, 0.3377227783203125),
        (-0.2309771329164505, 0.16552963852882385, 0.0030501079745590687),
        (0.034108299762010574, -0.29305559396743774, 0.10459622740745544)]),
    "multifractal": (dict(distortion=0.0, noise_type="MULTIFRACTAL"), [
        (1.3330360651016235, 0.8484621047973633, 1.3887478113174438),
        (0.5892728567123413, 1.1465405225753784, 1.3940644264221191),
        (0.9232122302055359, 0.8286771774291992, 0.9579874873161316),
        (1.0536088943481445, 1.0154823064804077, 1.0942007303237915)]),
    "hetero": (dict(distortion=0.7, noise_type="HETERO_TERRAIN", offset=0.5), [
        (0.9504186511039734, -0.1952226161956787, 1.053863763809204),
        (0.42806515097618103, 1.2191839218139648, 2.1361730098724365),
        (-0.08104714006185532, 1.1825189590454102, 0.8857415914535522),
        (0.8927666544914246, 0.7354680299758911, 0.9197658896446228)]),
    "fbm_2d": (dict(distortion=0.7, dimensions="2D"), [
        (0.4675045311450958, 0.5127296447753906, 0.6134202480316162),
        (0.6250163316726685, 0.3343081474304199, 0.4321138560771942),
        (0.49132972955703735, 0.42894113063812256, 0.5712411403656006),
        (0.4767652153968811, 0.5073117017745972, 0.3857783079147339)]),
    "fbm_1d": (dict(distortion=0.7, dimensions="1D", w=POINTS[:, 0]), [
        (0.7058748006820679, 0.45995238423347473, 0.4144093096256256),
        (0.5417360067367554, 0.7037479877471924, 0.5126373767852783),
        (0.48950064182281494, 0.46472615003585815, 0.5533328056335449),
        (0.5847235918045044, 0.2958205044269562, 0.45345044136047363)]),
    "ridged": (dict(distortion=0.0, noise_type="RIDGED_MULTIFRACTAL", offset=1.0, gain=2.0), [
        (1.2482879161834717, 1.3389400243759155, 0.9618716239929199),
        (0.6029956936836243, 1.5091549158096313, 1.0947118997573853),
        (0.8824813961982727, 0.9103604555130005, 1.4858307838439941),
        (1.7208493947982788, 0.7233628034591675, 1.6511085033416748)]),
}


def random_points(n=4000, seed=0, spread=3.0):
    return np.random.default_rng(seed).uniform(-spread, spread, (n, 3))


def tex(points, **kw):
    return noise_texture(points, **{**BASE, "distortion": 0.0, **kw})


# ----------------------------------------------------------------------------- Cycles values
@pytest.mark.parametrize("case", list(CYCLES))
def test_values_rendered_by_cycles(case):
    settings, expected = CYCLES[case]
    fac, color = tex(POINTS, **settings)
    np.testing.assert_allclose(color, expected, atol=5e-4)
    np.testing.assert_array_equal(fac, color[:, 0])


# ----------------------------------------------------------------------------- properties
def test_shapes_dtypes_and_determinism():
    p = random_points(100)
    fac, color = tex(p)
    assert fac.shape == (100,) and color.shape == (100, 3)
    assert fac.dtype == np.float64 and color.dtype == np.float64
    fac2, color2 = tex(p.copy())
    np.testing.assert_array_equal(color, color2)
    _, one = tex(p[7:8])                      # a point's value does not depend on the batch
    np.testing.assert_array_equal(one[0], color[7])


@pytest.mark.parametrize("noise_type", NOISE_TYPES)
@pytest.mark.parametrize("distortion", [0.0, 0.7])
def test_continuity(noise_type, distortion):
    p = random_points(2000)
    # Points straddling lattice planes too: coordinates k / scale -+ tiny.
    lattice = np.round(p * 5.0) / 5.0
    a = np.concatenate([p, lattice - 1e-9])
    b = np.concatenate([p + 1e-6, lattice + 1e-9])
    _, ca = tex(a, noise_type=noise_type, distortion=distortion)
    _, cb = tex(b, noise_type=noise_type, distortion=distortion)
    assert np.abs(ca - cb).max() < 1e-3


def test_normalized_fbm_range_and_mean():
    fac, color = tex(random_points(20000, spread=20.0), detail=4.0, roughness=0.5, lacunarity=2.0)
    assert color.min() > -0.02 and color.max() < 1.02
    assert abs(color.mean() - 0.5) < 0.02
    assert 0.05 < color.std() < 0.2


def test_raw_fbm_is_signed_and_unnormalized():
    fac, _ = tex(random_points(20000, spread=20.0), detail=4.0, roughness=0.5, normalize=False)
    assert fac.min() < -0.5 and fac.max() > 0.5 and abs(fac.mean()) < 0.05


@pytest.mark.parametrize("dims, cols", [("1D", []), ("2D", [0, 1]), ("3D", [0, 1, 2]), ("4D", [0, 1, 2])])
def test_detail_zero_is_one_octave(dims, cols):
    p = random_points(500)
    w = np.linspace(-2.0, 2.0, 500)
    coords = np.column_stack([p[:, cols]] + ([w] if dims in ("1D", "4D") else [])) * 5.0
    fac, _ = tex(p, detail=0.0, dimensions=dims, w=w)
    np.testing.assert_allclose(fac, noise(coords), atol=1e-12)
    raw, _ = tex(p, detail=0.0, dimensions=dims, w=w, normalize=False)
    np.testing.assert_allclose(raw, snoise(coords), atol=1e-12)


@pytest.mark.parametrize("noise_type", [t for t in NOISE_TYPES if t != "RIDGED_MULTIFRACTAL"])
@pytest.mark.parametrize("normalize", [True, False])
def test_fractional_detail_interpolates(noise_type, normalize):
    p = random_points(1000)
    kw = dict(noise_type=noise_type, normalize=normalize, offset=0.8, gain=1.5)
    lo, _ = tex(p, detail=2.0, **kw)
    hi, _ = tex(p, detail=3.0, **kw)
    mid, _ = tex(p, detail=2.25, **kw)
    np.testing.assert_allclose(mid, 0.75 * lo + 0.25 * hi, atol=1e-12)
    assert np.abs(hi - lo).max() > 0.01


def test_ridged_ignores_fractional_detail():
    p = random_points(300)
    a, _ = tex(p, detail=2.0, noise_type="RIDGED_MULTIFRACTAL", offset=1.0, gain=2.0)
    b, _ = tex(p, detail=2.9, noise_type="RIDGED_MULTIFRACTAL", offset=1.0, gain=2.0)
    np.testing.assert_array_equal(a, b)


def test_detail_and_roughness_are_clamped():
    p = random_points(200)
    np.testing.assert_array_equal(tex(p, detail=40.0)[1], tex(p, detail=15.0)[1])
    np.testing.assert_array_equal(tex(p, detail=-3.0)[1], tex(p, detail=0.0)[1])
    np.testing.assert_array_equal(tex(p, roughness=-1.0)[1], tex(p, roughness=0.0)[1])


def test_distortion_zero_is_a_noop_and_distortion_moves_points():
    p = random_points(500)
    direct = noise_select(p * 5.0, 2.5, 0.6, 2.3, 0.0, 1.0, "FBM", True)
    fac, _ = tex(p, distortion=0.0)
    np.testing.assert_allclose(fac, direct, atol=1e-6)  # settings rounded to float32 in tex
    tiny, _ = tex(p, distortion=1e-7)
    assert np.abs(tiny - fac).max() < 1e-5
    big, _ = tex(p, distortion=2.0)
    assert np.abs(big - fac).mean() > 0.02


def test_color_channels_differ_and_red_is_fac():
    fac, color = tex(random_points(500))
    np.testing.assert_array_equal(color[:, 0], fac)
    assert np.abs(color[:, 1] - fac).mean() > 0.03 and np.abs(color[:, 2] - color[:, 1]).mean() > 0.03


def test_dimension_modes_read_the_right_inputs():
    p = random_points(300)
    q = p.copy()
    q[:, 2] += 1.7
    np.testing.assert_array_equal(tex(p, dimensions="2D")[1], tex(q, dimensions="2D")[1])
    assert np.abs(tex(p)[1] - tex(q)[1]).max() > 0.05
    np.testing.assert_array_equal(tex(p, dimensions="1D", w=0.3)[1], tex(q * 3, dimensions="1D", w=0.3)[1])
    assert np.abs(tex(p, dimensions="4D", w=0.3)[1] - tex(p, dimensions="4D", w=0.5)[1]).max() > 0.05
    with pytest.raises(ValueError):
        tex(p, dimensions="5D")
    with pytest.raises(ValueError):
        tex(p, noise_type="VORONOI")


def test_perlin_is_zero_on_the_lattice_and_periodic_beyond():
    cells = np.random.default_rng(3).integers(-1000, 1000, (200, 3)).astype(np.float64)
    assert np.abs(perlin(cells)).max() == 0.0               # gradient noise vanishes at lattice points
    # C fmod keeps the sign: x and x + 100000 k agree when both have the same sign.
    sign = np.array([1.0, -1.0, 1.0])
    p = np.abs(random_points(200, spread=50.0)) * sign
    np.testing.assert_allclose(snoise(p + 100000.0 * np.array([1, 2, 3]) * sign), snoise(p), atol=1e-6)
    # Beyond 1e6 the coordinate is also shifted by half a cell (Cycles' precision correction).
    np.testing.assert_allclose(snoise(p + 2.0e6 * sign), snoise(p + 0.5), atol=1e-6)
    assert np.abs(snoise(p + 1.0e5 * sign) - snoise(p - 1.0e5 * sign)).max() > 0.1  # sign matters


# ----------------------------------------------------------------------------- texture_hash
def _lookup3_final_ref(a, b, c):
    m = 0xFFFFFFFF

    def rot(x, k):
        return ((x << k) | (x >> (32 - k))) & m
    for x, y, z, k in ((2, 1, 1, 14), (0, 2, 2, 11), (1, 0, 0, 25), (2, 1, 1, 16), (0, 2, 2, 4),
                       (1, 0, 0, 14), (2, 1, 1, 24)):
        v = [a, b, c]
        v[x] = ((v[x] ^ v[y]) - rot(v[z], k)) & m
        a, b, c = v
    return c


def test_hash_uint_matches_scalar_lookup3():
    keys = np.array([0, 1, 12345, 0xFFFFFFFF, 0x80000000], dtype=np.uint32)
    init = 0xDEADBEEF + (1 << 2) + 13
    expected = [_lookup3_final_ref((init + int(k)) & 0xFFFFFFFF, init, init) for k in keys]
    np.testing.assert_array_equal(th.hash_uint(keys), np.array(expected, dtype=np.uint32))
    np.testing.assert_array_equal(th.hash_uint(np.array([-1])), th.hash_uint(np.array([0xFFFFFFFF])))
    init2 = 0xDEADBEEF + (2 << 2) + 13
    assert int(th.hash_uint2(7, 9)) == _lookup3_final_ref(init2 + 7, init2 + 9, init2)


def test_float_hashes_shapes_and_forms():
    rng = np.random.default_rng(1)
    k = rng.normal(size=(5, 7, 4)).astype(np.float32)
    h = th.hash_float4_to_float(k)
    assert h.shape == (5, 7) and h.dtype == np.float64 and 0.0 <= h.min() and h.max() <= 1.0
    np.testing.assert_array_equal(h, th.hash_float4_to_float(*np.moveaxis(k, -1, 0)))
    np.testing.assert_array_equal(th.hash_float3_to_float3(k[..., :3])[..., 0],
                                  th.hash_float3_to_float(k[..., :3]))
    assert th.hash_float3_to_color(1.0, 2.0, 3.0).shape == (3,)
    assert th.hash_float2_to_float3(k[..., 0], 1.0).shape == (5, 7, 3)
    # Float keys are their float32 bit patterns: float64 keys hash like their float32 rounding.
    np.testing.assert_array_equal(th.hash_float_to_float(k[..., 0].astype(np.float64)),
                                  th.hash_float_to_float(k[..., 0]))
    assert th.hash_float_to_float(0.0) != th.hash_float_to_float(-0.0)
