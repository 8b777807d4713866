import bpy, numpy as np, math
import blender_scenes as bs
from test_addon_parity import use_cycles, OURS

def build(cam_z, block):
    bs.empty_scene((32, 32), **dict(OURS, passes=16))
    bs.plane("Floor", size=40.0, material=bs.diffuse("Floor", (0.5, 0.5, 0.5)))
    if block:
        bs.cube("Slab", size=1.0, material=bs.glass("G", ior=1.45), location=(0, 0, 0.75), scale=(1.5, 1.5, 1.5))
    else:
        bs.cube("Slab", size=1.0, material=bs.glass("G", ior=1.45), location=(0, 0, 2.0), scale=(30, 30, 0.2))
    bs.camera(location=(0, 0, cam_z), target=(0, 0, 0), lens=50.0)
    bs.world((1.0, 1.0, 1.0), strength=1.0)

def test_tmp(addon, tmp_path):
    for cam_z, block in ((1.0, False), (4.0, False), (4.0, True)):
        build(cam_z, block); use_cycles(bpy.context.scene); bpy.context.scene.cycles.samples = 1024
        c = bs.render_exr(tmp_path / "c.exr")
        build(cam_z, block)
        o = bs.render_exr(tmp_path / "o.exr")
        print("glass", cam_z, block, "cycles", c[..., :3].mean(), "ours", o[..., :3].mean(), "ratio", o[..., :3].mean() / c[..., :3].mean())
