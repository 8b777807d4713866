"""`make extension`'s zip installs into an isolated Blender user directory, enables and renders.

Builds the zips with tools/build_extension.py (Blender's own builder; the embreex
wheels are downloaded once into build/wheels), then, in a fresh process with
BLENDER_USER_RESOURCES pointing at a temporary folder, installs the Linux x64 zip
with ``bpy.ops.extensions.package_install_files``, opens a sample scene and
renders it with two worker processes started from the installed copy.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile

import numpy as np

import blender_scenes as bs

INSTALL_AND_RENDER = r"""
import json, os, sys
import bpy
zip_path, blend, out = sys.argv[1:4]
bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
module = sys.modules["bl_ext.user_default.amcmcppm"]
bpy.ops.wm.open_mainfile(filepath=blend)
scene = bpy.context.scene
p = scene.amcmcppm
p.passes, p.time_limit, p.photons_per_pass, p.workers, p.chains = 2, 0.0, 4000, 2, 512
scene.render.resolution_percentage = 10
s = scene.render.image_settings
s.file_format, s.color_depth, s.color_mode = "OPEN_EXR", "32", "RGBA"
scene.render.filepath = out
scene.render.use_file_extension = False
bpy.ops.render.render(write_still=True)
print("RESULT " + json.dumps({"module": module.__file__, "engine": scene.render.engine}))
"""


def test_extension_zip_installs_and_renders(repo_root, tmp_path):
    sys.path.insert(0, str(repo_root / "tools"))
    try:
        import build_extension
    finally:
        sys.path.pop(0)
    dist = tmp_path / "dist"
    build_extension.main(["--output-dir", str(dist), "--build-dir", str(tmp_path / "build")])
    zips = {z.name: z for z in dist.glob("*.zip")}
    assert set(zips) == {"amcmcppm-0.1.0-linux_x64.zip", "amcmcppm-0.1.0-windows_x64.zip",
                         "amcmcppm-0.1.0-macos_arm64.zip"}
    for name, path in zips.items():
        members = zipfile.ZipFile(path).namelist()
        wheels = [m for m in members if m.startswith("wheels/")]
        assert len(wheels) == 1 and "embreex" in wheels[0]
        assert not any("numpy" in m for m in members)
        assert "core/__init__.py" in members and "amcmcppm_addon/engine.py" in members
        assert not any(m.startswith(("tests/", "sample_blends/")) or "__pycache__" in m for m in members)

    resources = tmp_path / "user"
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(resources))
    env.pop("PYTHONPATH", None)
    out = tmp_path / "installed.exr"
    linux_zip = zips["amcmcppm-0.1.0-linux_x64.zip"]
    proc = subprocess.run([sys.executable, "-c", INSTALL_AND_RENDER, str(linux_zip),
                           str(repo_root / "sample_blends" / "cornell_box.blend"), str(out)],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    result = json.loads(proc.stdout.split("RESULT ", 1)[1].splitlines()[0])
    assert result["engine"] == "AMCMCPPM"
    assert result["module"].startswith(str(resources / "extensions" / "user_default" / "amcmcppm"))
    site = resources / "extensions" / ".local" / "lib" / "python3.11" / "site-packages"
    assert (site / "embreex").is_dir(), "the embreex wheel was not installed"
    img = bs.read_exr(out)
    assert img.shape == (25, 25, 4) and np.isfinite(img).all() and img[..., :3].mean() > 0
