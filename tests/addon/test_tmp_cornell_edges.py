import numpy as np
import bpy
import blender_scenes as bs
from test_addon_samples import open_sample
from test_addon_parity import use_cycles


def test_cornell_edges(addon, repo_root, tmp_path):
    res = {}
    for which in ("cycles", (False, True), (True, True), (False, False), (True, False)):
        scene = open_sample(repo_root, "cornell_box")
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 128, 96, 100
        p = scene.amcmcppm
        p.passes, p.time_limit, p.workers, p.photons_per_pass, p.seed = 40, 0.0, 2, 100000, 3
        if which == "cycles":
            use_cycles(scene)
            scene.cycles.samples = 4096
        else:
            p.edge_coverage, p.bias_correction = which
        res[which] = bs.render_exr(tmp_path / f"{which}.exr")[..., :3].astype(np.float64)
    cyc = res.pop("cycles")
    for k, img in res.items():
        rel = (((img - cyc) ** 2) / (cyc ** 2 + 0.01)).mean()
        r = img.mean(axis=2) / np.maximum(cyc.mean(axis=2), 1e-4)
        print(f"coverage {k[0]} correction {k[1]}: relMSE {rel:.5f}, mean ratio {img.mean() / cyc.mean():.4f}, "
              f"ratio 1st/99th pct {np.percentile(r[cyc.mean(axis=2) > 0.01], [1, 99])}")
