"""method="auto": the chains' first pass, then uniform photons where many uniform paths are visible
(aimed ones where the photons from afar are aimed)."""
import numpy as np
import pytest

from core import RenderSettings, render
from core.settings import AUTO_AIMED_VISIBLE, AUTO_UNIFORM_VISIBLE
from core.testing.scenes import SUNLIT_CORNER_SUN, cornell_box, glass_ceiling_room, sunlit_corner

# (plain estimates: the first test rebuilds PPM's passes 2..6 from its images after 1 and 6)
FAST = dict(photons_per_pass=20_000, chains=2048, bias_correction=False)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_scene_mostly_in_view_goes_on_with_uniform_photons_after_the_first_pass(workers):
    """A closed room seen whole: the image of passes 2..6 is PPM's passes 2..6 to float32 rounding
    (the same random streams and radii), without the chains' first pass."""
    scene = cornell_box((24, 24))
    auto = render(scene, RenderSettings(method="auto", passes=6, seed=1, workers=workers, **FAST))
    assert [s["method"] for s in auto.stats] == ["amcmcppm"] + ["ppm"] * 5
    assert auto.stats[0]["visible_fraction_pass"] >= AUTO_UNIFORM_VISIBLE
    assert auto.stats[0]["proposals"] > 0 and auto.stats[-1]["proposals"] == 0
    assert auto.method == "ppm" and auto.passes == 5
    images = []
    ppm = render(scene, RenderSettings(method="ppm", passes=6, seed=1, workers=workers, **FAST),
                 on_iteration=lambda r: images.append(r.image.astype(np.float64)))
    # Passes of equal size weigh the same: passes 2..6 = (6 x image after 6 - image after 1) / 5.
    later = (6.0 * images[-1] - images[0]) / 5.0
    np.testing.assert_allclose(auto.image, later, rtol=1e-5, atol=1e-6 * later[..., :3].max())
    assert auto.image[..., :3].mean() > 0 and np.array_equal(ppm.image, images[-1].astype(np.float32))


def test_a_room_seen_through_glass_keeps_the_chains_and_renders_as_amcmcppm():
    scene = glass_ceiling_room((16, 12))
    auto = render(scene, RenderSettings(method="auto", passes=3, seed=2, workers=1, **FAST))
    chains = render(scene, RenderSettings(method="amcmcppm", passes=3, seed=2, workers=1, **FAST))
    assert auto.stats[0]["visible_fraction_pass"] < AUTO_UNIFORM_VISIBLE
    assert auto.method == "amcmcppm" and all(s["method"] == "amcmcppm" for s in auto.stats)
    np.testing.assert_array_equal(auto.image, chains.image)


def test_a_render_stopped_at_the_switch_keeps_the_first_image():
    """The image of the uniform passes starts empty; until one lands, the first pass's stands."""
    seen = []
    result = render(cornell_box((24, 24)), RenderSettings(method="auto", passes=0, time_limit=1e3, seed=1,
                                                          workers=1, **FAST),
                    on_iteration=lambda r: seen.append(r.image.copy()), should_stop=lambda: len(seen) >= 1)
    assert result.interrupted and result.passes == 1 and result.method == "amcmcppm"
    assert result.image[..., :3].mean() > 0
    np.testing.assert_array_equal(result.image, seen[0])


def test_aimed_photons_often_visible_go_on_uniform():
    """A 600 mm lens on a corner of a 200 m sunlit floor: aimed at what the camera sees
    (``focus_photons``), some 16 % of the first pass's uniform samples are visible (about 0.1 %
    unaimed), so "auto" goes on with aimed uniform photons (``AUTO_AIMED_VISIBLE``; measured ahead
    of the chains there, benchmarks/focus_cost.py) and the image is the closed form's; unaimed,
    it keeps the chains."""
    scene = sunlit_corner()
    auto = render(scene, RenderSettings(method="auto", passes=3, seed=1, workers=1, **FAST))
    assert [s["method"] for s in auto.stats] == ["amcmcppm", "ppm", "ppm"]
    assert AUTO_AIMED_VISIBLE <= auto.stats[0]["visible_fraction_pass"] < AUTO_UNIFORM_VISIBLE
    assert all(s["focus_radius"] > 0 for s in auto.stats)
    expected = 0.6 * 4.0 * -SUNLIT_CORNER_SUN[2] / np.pi       # albedo E cos / pi (the defaults)
    assert abs(auto.image[..., :3].mean() / expected - 1.0) < 0.05
    unaimed = render(scene, RenderSettings(method="auto", passes=2, seed=1, workers=1, focus_photons=False,
                                           **FAST))
    assert unaimed.stats[0]["visible_fraction_pass"] < AUTO_AIMED_VISIBLE
    assert unaimed.method == "amcmcppm" and all(s["method"] == "amcmcppm" for s in unaimed.stats)
