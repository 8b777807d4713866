"""Cryptomatte passes (core/cryptomatte.py): ids, coverage through transparent surfaces, slots; and
Shader AOVs (Materials.aov_*): the other passes of ids and masks a compositor picks from."""
import numpy as np
import pytest

from core import Camera, Lights, Materials, RenderSettings, Scene, SceneError, render
from core.cryptomatte import CryptoSums, hash_to_float, murmur3_32, name_id
from core.testing.scenes import MeshBuilder


def test_murmur3_and_the_float_ids_are_cryptomatte_s():
    """MurmurHash3_x86_32 (seed 0) against published values, and Cycles' float of a hash: its bits,
    the exponent kept within 1..254 (finite, not 0)."""
    for data, want in ((b"", 0x0), (b"hello", 0x248BFA47), (b"Hello, world!", 0xC0363E43),
                       (b"The quick brown fox jumps over the lazy dog", 0x2E4FF723)):
        assert murmur3_32(data) == want, data
    assert np.float32(hash_to_float(0x3F800000)) == np.float32(1.0)
    for h in (0x0, 0x7F800000, 0xFFFFFFFF, 0x807FFFFF):
        assert np.isfinite(hash_to_float(h)) and hash_to_float(h) != 0.0
    value, hex_ = name_id("Cube")
    assert hex_ == f"{murmur3_32(b'Cube'):08x}" and np.float32(value).view(np.uint32) == murmur3_32(b"Cube")


def sheets_scene(opacities, tint=(1.0, 1.0, 1.0)):
    """Sheets of ``opacities`` (tinted ``tint`` where they let light through) one behind the other
    before an opaque wall, filling the view of a 6 x 4 camera; ids 1, 2, ... and the wall's 9."""
    specs = [{"name": "wall", "diffuse": 0.5}] + [
        {"name": f"sheet{i}", "diffuse": 0.5, "opacity": a, "transparent_color": tint}
        for i, a in enumerate(opacities)]
    m = MeshBuilder()
    m.add_quad((-50, 10, -50), (50, 10, -50), (50, 10, 50), (-50, 10, 50), 0)
    for i in range(len(opacities)):
        y = 2.0 + i
        m.add_quad((-50, y, -50), (50, y, -50), (50, y, 50), (-50, y, 50), i + 1)
    sun = Lights.build([{"kind": "sun", "direction": (0, 1, 0), "power": 1.0}])
    scene = m.build(Materials.build(specs), sun, Camera.look_at((0, 0, 0), (0, 1, 0), resolution=(6, 4)))
    ids = np.where(scene.material_ids == 0, 9.0, scene.material_ids.astype(np.float32))
    return scene.replace(cryptomatte_ids=np.repeat(ids[:, None], 3, axis=1).astype(np.float32))


def test_coverage_follows_every_crossing_with_what_reaches_it():
    """Two sheets of opacity 0.3 and 0.5 before a wall: 0.3, 0.7 x 0.5 = 0.35 and the rest 0.35 in
    every pixel, by decreasing coverage (the tie in either order), the levels after them 0; a
    tinted sheet (transparent colour 0.5) lets half as much through: 0.3 and 0.35; a pixel's
    coverages add up to 1 where the wall closes the view.  The passes are finite and only the
    levels asked for."""
    result = render(sheets_scene([0.3, 0.5]), RenderSettings(passes=2, photons_per_pass=200, workers=1,
                                                             data_passes=("crypto_object", "crypto_asset"),
                                                             cryptomatte_levels=4))
    image = result.data["crypto_object"]
    assert image.shape == (4, 6, 8) and np.isfinite(image).all() and "crypto_material" not in result.data
    levels = image.reshape(-1, 4, 2)
    np.testing.assert_allclose(levels[:, 0, 1], 0.35, atol=1e-6)
    np.testing.assert_allclose(levels[:, 1, 1], 0.35, atol=1e-6)
    np.testing.assert_allclose(levels[:, 2], np.tile([1.0, 0.3], (24, 1)), atol=1e-6)
    assert set(np.unique(levels[:, :2, 0])) == {2.0, 9.0} and (levels[:, 3] == 0).all()
    tinted = render(sheets_scene([0.4], tint=(0.5, 0.5, 0.5)),
                    RenderSettings(passes=1, photons_per_pass=200, workers=1, data_passes=("crypto_object",)))
    levels = tinted.data["crypto_object"].reshape(-1, 6, 2)
    # Cycles' matte weight 1 - mean(transparency) = 1 - 0.6 x 0.5 at the sheet, then 0.3 reaches the wall.
    np.testing.assert_allclose(levels[:, 0], np.tile([1.0, 0.7], (24, 1)), atol=1e-6)
    np.testing.assert_allclose(levels[:, 1], np.tile([9.0, 0.3], (24, 1)), atol=1e-6)


def test_crypto_sums_keep_the_levels_of_most_coverage_per_pixel():
    sums = CryptoSums()
    sums.add([0, 0, 1, 0], np.float32([5.0, 7.0, 5.0, 5.0]), [0.2, 0.5, 1.0, 0.4])
    sums.add([0, 2], np.float32([8.0, 7.0]), [0.1, 0.3])
    out = sums.image(3, 2, passes=2)
    np.testing.assert_allclose(out[0], [5.0, 0.3, 7.0, 0.25])       # 8's 0.05 falls past two levels
    np.testing.assert_allclose(out[1], [5.0, 0.5, 0.0, 0.0])
    np.testing.assert_allclose(out[2], [7.0, 0.15, 0.0, 0.0])
    assert (CryptoSums().image(2, 3, passes=0) == 0).all()


def test_cryptomatte_ids_survive_a_file_round_trip_and_bad_values_are_refused(tmp_path):
    scene = sheets_scene([0.5])
    scene.save(tmp_path / "s.npz")
    np.testing.assert_array_equal(Scene.load(tmp_path / "s.npz").cryptomatte_ids, scene.cryptomatte_ids)
    with pytest.raises(SceneError, match="cryptomatte_ids"):
        scene.replace(cryptomatte_ids=scene.cryptomatte_ids[:, :2]).validate()
    with pytest.raises(ValueError, match="cryptomatte_levels"):
        RenderSettings(cryptomatte_levels=0)
    # Without ids the passes are not made (the scene has none to show).
    plain = render(scene.replace(cryptomatte_ids=None),
                   RenderSettings(passes=1, photons_per_pass=100, workers=1, data_passes=("crypto_object",)))
    assert "crypto_object" not in plain.data


def test_shader_aovs_are_written_where_the_camera_rays_stop(tmp_path):
    """Materials' Shader AOVs (``Materials.aov_*``, data passes "aov:" + name): the wall writes a
    colour "mask" and a program of its position into "height", the card another mask and no
    height; (H, W, 4) with 1 in the fourth channel where written, 0 elsewhere; a name no material
    writes gives zeros; the AOVs survive a file round trip; a bad program index is refused."""
    from test_render_basics import wall_and_card
    camera = Camera.look_at((0, 0, 0), (0, 1, 0), resolution=(16, 12), lens_mm=20.0)
    scene = wall_and_card(camera, sheet=False)
    specs = [{"name": "wall", "diffuse": 0.5,
              "aovs": {"mask": [1.0, 0.5, 0.25], "height": {"op": "attribute", "name": "position"}}},
             {"name": "card", "diffuse": 0.8, "aovs": {"mask": 2.0}}]
    scene = scene.replace(materials=Materials.build(specs))
    data = render(scene, RenderSettings(passes=2, photons_per_pass=200, workers=1,
                                        data_passes=("aov:mask", "aov:height", "aov:none"))).data
    mask, height = data["aov:mask"], data["aov:height"]
    assert mask.shape == (12, 16, 4) and (data["aov:none"] == 0).all()
    assert (mask[..., 3] == 1.0).all()                       # (every pixel sees the wall or the card)
    card = (mask == [2.0, 2.0, 2.0, 1.0]).all(axis=-1)
    wall = (mask == [1.0, 0.5, 0.25, 1.0]).all(axis=-1)
    # Only the card's edges mix the two (a pixel's passes see either).
    assert card.sum() > 4 and wall.sum() > 150 and (~card & ~wall).sum() < 20
    assert (height[card] == 0).all()
    # The wall at y = 4: the height is the point's position (x, 4, z), averaged over the passes.
    np.testing.assert_allclose(height[wall][:, 1], 4.0, atol=1e-4)
    assert np.ptp(height[wall][:, 0]) > 4.0 and (height[wall][:, 3] == 1.0).all()
    scene.save(tmp_path / "s.npz")
    loaded = Scene.load(tmp_path / "s.npz").materials
    assert loaded.aov_names == ["height", "mask"]
    np.testing.assert_array_equal(loaded.aov_program, scene.materials.aov_program)
    bad = Materials.build(specs)
    bad.aov_program[0, 0] = 5
    with pytest.raises(SceneError, match="aov_program"):
        scene.replace(materials=bad).validate()
