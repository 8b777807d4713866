"""render.py as a command line tool (``python render.py scene.blend ...`` with the bpy module)."""
from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

import blender_scenes as bs

FAST = ["--passes", "2", "--photons-per-pass", "3000", "--workers", "1", "--chains", "256",
        "--resolution-percentage", "10"]


def run(repo_root, *args, timeout=300):
    return subprocess.run([sys.executable, str(repo_root / "render.py"), *map(str, args)], cwd=repo_root,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def cornell(repo_root):
    return repo_root / "sample_blends" / "cornell_box.blend"


def test_renders_exr_png_and_stats(repo_root, cornell, tmp_path):
    out = run(repo_root, cornell, "--output", tmp_path / "c.exr", "--png", tmp_path / "c.png",
              "--stats", tmp_path / "stats.jsonl", "--method", "ppm", "--seed", "3", "--max-bounces", "4",
              "--alpha", "0.5", "--initial-radius", "2", *FAST)
    assert out.returncode == 0, out.stderr
    assert "render.py: wrote" in out.stdout
    img = bs.read_exr(tmp_path / "c.exr")
    assert img.shape == (25, 25, 4) and np.isfinite(img).all() and img[..., :3].mean() > 0
    assert (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    stats = [json.loads(x) for x in (tmp_path / "stats.jsonl").read_text().splitlines()]
    assert [s["pass"] for s in stats] == [1, 2]
    assert all(s["method"] == "ppm" for s in stats)


def test_snapshots_until_the_last_time(repo_root, cornell, tmp_path):
    """Without --passes/--time-limit the render runs until the last snapshot time."""
    args = [a for a in FAST if a not in ("--passes", "2")]
    out = run(repo_root, cornell, "--output", tmp_path / "s.exr", "--snapshot-times", "0.000001,1.5",
              "--snapshot-dir", tmp_path / "snaps", "--stats", tmp_path / "stats.jsonl", *args)
    assert out.returncode == 0, out.stderr
    index = [json.loads(x) for x in (tmp_path / "snaps" / "snapshots.jsonl").read_text().splitlines()]
    assert [e["time"] for e in index] == [0.000001, 1.5]
    for e in index:
        snap = bs.read_exr(tmp_path / "snaps" / e["file"])
        assert snap.shape == (25, 25, 4) and np.isfinite(snap).all()
    stats = [json.loads(x) for x in (tmp_path / "stats.jsonl").read_text().splitlines()]
    # The last snapshot is the final image.  The core ends at the limit, or up to one pass before
    # it when it skips a pass the limit would cut short (RenderOutputs.finish): 1.498 s was seen.
    elapsed = [s["elapsed_s"] for s in stats]
    longest = max(np.diff([0.0] + elapsed))
    assert index[0]["pass"] == 1 and index[1]["pass"] == stats[-1]["pass"]
    assert elapsed[-1] + longest >= 1.5 and (len(elapsed) < 2 or elapsed[-2] < 1.5)


def test_border_and_resolution_flags(repo_root, cornell, tmp_path):
    out = run(repo_root, cornell, "--output", tmp_path / "b.exr", "--resolution", "40", "30",
              "--border", "0.25", "0.75", "0.0", "0.5", *FAST[:-2])
    assert out.returncode == 0, out.stderr
    assert bs.read_exr(tmp_path / "b.exr").shape == (30, 40, 4)   # Blender keeps the full frame


def test_a_stereo_file_renders_the_cameras_own_view(addon, repo_root, cornell, tmp_path):
    """A file with Stereoscopy on: render.py turns it off, says so and writes --output (before: Blender
    wrote b_L.exr and b_R.exr, and render.py exited 1, "was not written")."""
    import bpy
    bpy.ops.wm.open_mainfile(filepath=str(cornell))
    bpy.context.scene.render.use_multiview = True
    stereo = tmp_path / "stereo.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(stereo), copy=True)
    out = run(repo_root, stereo, "--output", tmp_path / "s.exr", *FAST)
    assert out.returncode == 0, out.stderr
    assert "Stereoscopy turned off" in out.stdout
    assert np.isfinite(bs.read_exr(tmp_path / "s.exr")).all()


@pytest.mark.parametrize("args,pattern", [
    (["--bogus"], r"unrecognized arguments: --bogus"),
    (["--method", "bpt"], r"argument --method: invalid choice"),
    (["--target-acceptance", "1.5"], r"--target-acceptance 1.5 is outside the allowed range"),
    (["--transparent-bounces", "2000"], r"--transparent-bounces 2000 is outside the allowed range"),
    (["--output", "x.bmpx"], r"unknown image type '.bmpx'"),
    (["--snapshot-times", "1,soon"], r"--snapshot-times '1,soon': expected numbers"),
])
def test_bad_arguments_exit_2_with_one_line(repo_root, cornell, tmp_path, args, pattern):
    base = ["--output", tmp_path / "x.exr"] if "--output" not in args else []
    out = run(repo_root, cornell, *base, *args)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("render.py: error:") and re.search(pattern, lines[0])


def test_missing_blend_exits_2(repo_root, tmp_path):
    out = run(repo_root, tmp_path / "nope.blend", "--output", tmp_path / "x.exr")
    assert out.returncode == 2
    assert out.stderr.strip() == f"render.py: error: no such .blend file: {tmp_path / 'nope.blend'}"


def test_render_failure_exits_1_with_reason(repo_root, cornell, tmp_path):
    out = run(repo_root, cornell, "--output", tmp_path / "x.exr", "--passes", "0", "--time-limit", "0")
    assert out.returncode == 1
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("render.py: error:") and "'Passes' and 'Time Limit' are both 0" in last


def test_flags_mirror_the_core_cli(repo_root):
    """Every setting flag of ``python -m core render`` exists in render.py with the same name."""
    sys.path.insert(0, str(repo_root))
    try:
        import render as render_script
        from core.__main__ import build_parser as core_parser
    finally:
        sys.path.remove(str(repo_root))
    ours = {opt for a in render_script.build_parser()._actions for opt in a.option_strings}
    core_render = next(a for a in core_parser()._actions if a.dest == "command").choices["render"]
    theirs = {opt for a in core_render._actions for opt in a.option_strings}
    # (and the data passes: in Blender the view layer's boxes ask for them)
    not_settings = {"--builtin", "--resolution", "--png", "--quiet", "-q", "-h", "--help", "-o", "--output",
                    "--data-passes"}
    missing = (theirs - not_settings) - ours
    assert not missing, f"render.py lacks core flags {sorted(missing)}"
    # And every panel setting has a flag.
    panel = set(render_script.SETTING_FLAGS.values())
    from amcmcppm.amcmcppm_addon.properties import CORE_SETTING_NAMES
    assert set(CORE_SETTING_NAMES) == panel


def test_bias_correction_flag_reaches_the_render(repo_root, cornell, tmp_path):
    """--no-bias-correction renders the plain estimate (weight 0 in every pass); by default the
    weight of the kernel-bias correction is in the statistics from the fourth pass on."""
    weights = {}
    for flag in ("--bias-correction", "--no-bias-correction"):
        stats_path = tmp_path / f"{flag}.jsonl"
        out = run(repo_root, cornell, "--output", tmp_path / "c.exr", "--stats", stats_path, "--method", "ppm",
                  flag, *FAST, "--passes", "5")
        assert out.returncode == 0, out.stderr
        weights[flag] = [json.loads(x)["bias_weight"] for x in stats_path.read_text().splitlines()]
    assert len(weights["--bias-correction"]) == 5
    assert weights["--no-bias-correction"] == [0.0] * 5
    assert weights["--bias-correction"][:3] == [0.0] * 3 and weights["--bias-correction"][-1] > 0


def test_pixel_jitter_flag_reaches_the_render(repo_root, cornell, tmp_path):
    """--pixel-jitter: the default is stratified (the same image as with the flag), random another
    image of the same mean (within 3 %: 2 passes of 3,000 photons), and each is the same again."""
    images = {}
    random = ("--pixel-jitter", "random")
    for name, flags in (("default", ()), ("stratified", ("--pixel-jitter", "stratified")), ("random", random),
                        ("random again", random)):
        out = run(repo_root, cornell, "--output", tmp_path / "c.exr", "--method", "ppm", *FAST, *flags)
        assert out.returncode == 0, out.stderr
        images[name] = bs.read_exr(tmp_path / "c.exr")[..., :3]
    np.testing.assert_array_equal(images["default"], images["stratified"])
    np.testing.assert_array_equal(images["random"], images["random again"])
    assert not np.array_equal(images["random"], images["stratified"])
    assert images["random"].mean() == pytest.approx(images["stratified"].mean(), rel=0.03)


def test_focus_photons_flag_reaches_the_render(repo_root, tmp_path):
    """small_view.blend (a long lens on a glass ball in a sunlit town) with PPM: by default (and with
    --focus-photons) many times more of the uniform photons reach what the camera sees than with
    --no-focus-photons, which renders every photon from anywhere on the scene's disc."""
    blend = repo_root / "sample_blends" / "small_view.blend"
    visible = {}
    for flags in ((), ("--focus-photons",), ("--no-focus-photons",)):
        stats_path = tmp_path / "s.jsonl"
        out = run(repo_root, blend, "--output", tmp_path / "s.exr", "--stats", stats_path, "--method", "ppm",
                  *FAST, "--photons-per-pass", "20000", *flags)
        assert out.returncode == 0, out.stderr
        lines = [json.loads(x) for x in stats_path.read_text().splitlines()]
        visible[flags] = sum(x["uniform_visible"] for x in lines) / sum(x["uniform_samples"] for x in lines)
    print(f"visible shares of the uniform photons: {visible}")
    assert visible[()] == visible[("--focus-photons",)]
    assert visible[()] > 20 * visible[("--no-focus-photons",)]


def test_a_bounce_flag_overrides_cycles_light_paths(repo_root, cornell, tmp_path):
    """The sample takes Cycles' Light Paths; --diffuse-bounces 0 switches it to the engine's own
    limits (Cycles' others kept) with no diffuse bounce: the Cornell box keeps its direct light
    alone (measured 0.55 of the mean)."""
    means = {}
    for flags in ((), ("--diffuse-bounces", "0")):
        out = run(repo_root, cornell, "--output", tmp_path / "c.exr", "--method", "ppm", *FAST, *flags)
        assert out.returncode == 0, out.stderr
        means[flags] = bs.read_exr(tmp_path / "c.exr")[..., :3].mean()
    ratio = means[("--diffuse-bounces", "0")] / means[()]
    print(f"diffuse 0 / Cycles' limits: {ratio:.3f}")
    assert ratio < 0.85


def test_a_caustics_flag_overrides_cycles_light_paths(repo_root, tmp_path):
    """glass_ceiling.blend, a room lit only through a glass roof, takes Cycles' Light Paths (both
    Caustics on); --no-caustics-refractive switches it to the engine's own, with the light through
    the glass gone from every diffuse surface: the room is black (the camera sees no light)."""
    blend = repo_root / "sample_blends" / "glass_ceiling.blend"
    means = {}
    for flags in ((), ("--no-caustics-refractive",)):
        out = run(repo_root, blend, "--output", tmp_path / "g.exr", "--method", "ppm", *FAST, *flags)
        assert out.returncode == 0, out.stderr
        means[flags] = bs.read_exr(tmp_path / "g.exr")[..., :3].mean()
    print(f"glass_ceiling.blend means, Refractive Caustics on and off: {means}")
    assert means[()] > 0.1 and means[("--no-caustics-refractive",)] == 0.0


def test_direct_light_flags_reach_the_render(repo_root, cornell, tmp_path):
    """--direct-light sampled --direct-samples 3: three light samples per measurement point and
    pass in the statistics (none with --direct-light photons), and the Cornell box's mean as with
    photons (the light samples carry the direct light the photons' first vertices did)."""
    photons = ("--direct-light", "photons")
    sampled = ("--direct-light", "sampled", "--direct-samples", "3")
    means, samples = {}, {}
    for flags in (photons, sampled):
        stats_path = tmp_path / f"{len(flags)}.jsonl"
        out = run(repo_root, cornell, "--output", tmp_path / "c.exr", "--stats", stats_path,
                  "--method", "ppm", *FAST, "--passes", "4", "--photons-per-pass", "20000", *flags)
        assert out.returncode == 0, out.stderr
        stats = [json.loads(x) for x in stats_path.read_text().splitlines()]
        samples[flags] = [s["light_samples"] / s["measurement_points"] for s in stats]
        means[flags] = bs.read_exr(tmp_path / "c.exr")[..., :3].mean()
    assert samples[photons] == [0.0] * 4
    assert samples[sampled] == [3.0] * 4
    ratio = means[sampled] / means[photons]
    print(f"sampled / photons: {ratio:.3f}")
    assert ratio == pytest.approx(1.0, abs=0.04)
