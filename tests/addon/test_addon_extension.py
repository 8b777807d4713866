"""`make extension`'s zip installs into an isolated Blender user directory, enables and renders.

Builds the zips with tools/build_extension.py (Blender's own builder; the embreex
wheels are downloaded once into build/wheels).  Then, in a fresh process with
BLENDER_USER_RESOURCES pointing at a temporary folder, installs the Linux x64 zip
with ``bpy.ops.extensions.package_install_files``, opens a sample scene and renders
it.  That process runs in an interpreter that sees every package of this one
*except embreex*, as Blender's bundled Python does: embreex must come from the
extension's wheel, in Blender's process and in the photon worker processes.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import zipfile

import numpy as np
import pytest

import blender_scenes as bs

ZIP = "amcmcppm-0.1.0-linux_x64.zip"

INSTALL_AND_RENDER = r"""
import json, sys
import bpy
zip_path, blend, out, workers = sys.argv[1:5]
try:
    import embreex
    raise SystemExit("embreex is importable before the extension is installed: " + embreex.__file__)
except ImportError:
    pass
bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
module = sys.modules["bl_ext.user_default.amcmcppm"]
import embreex
bpy.ops.wm.open_mainfile(filepath=blend)
scene = bpy.context.scene
p = scene.amcmcppm
p.passes, p.time_limit, p.photons_per_pass, p.workers, p.chains = 2, 0.0, 4000, int(workers), 512
scene.render.resolution_percentage = 10
s = scene.render.image_settings
s.file_format, s.color_depth, s.color_mode = "OPEN_EXR", "32", "RGBA"
scene.render.filepath = out
scene.render.use_file_extension = False
bpy.ops.render.render(write_still=True)
print("RESULT " + json.dumps({"module": module.__file__, "engine": scene.render.engine,
                              "embreex": embreex.__file__}))
"""


@pytest.fixture(scope="module")
def extension_zips(repo_root, tmp_path_factory):
    sys.path.insert(0, str(repo_root / "tools"))
    try:
        import build_extension
    finally:
        sys.path.pop(0)
    tmp = tmp_path_factory.mktemp("extension")
    dist = tmp / "dist"
    build_extension.main(["--output-dir", str(dist), "--build-dir", str(tmp / "build")])
    return {z.name: z for z in dist.glob("*.zip")}


@pytest.fixture(scope="module")
def python_without_embreex(tmp_path_factory):
    """A venv linking every package of this interpreter except embreex (like Blender's Python)."""
    venv = tmp_path_factory.mktemp("blender_like_python")
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    site = sysconfig.get_paths()["purelib"]
    target = venv / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    for entry in os.listdir(site):
        if not entry.lower().startswith("embreex"):
            os.symlink(os.path.join(site, entry), target / entry)
    return venv / "bin" / "python"


def test_zips_hold_the_package_and_one_wheel_each(extension_zips):
    assert set(extension_zips) == {ZIP, "amcmcppm-0.1.0-windows_x64.zip", "amcmcppm-0.1.0-macos_arm64.zip"}
    for path in extension_zips.values():
        members = zipfile.ZipFile(path).namelist()
        wheels = [m for m in members if m.startswith("wheels/")]
        assert len(wheels) == 1 and "embreex" in wheels[0]
        assert not any("numpy" in m for m in members)
        assert "core/__init__.py" in members and "amcmcppm_addon/engine.py" in members
        assert not any(m.startswith(("tests/", "sample_blends/")) or "__pycache__" in m for m in members)


@pytest.mark.parametrize("workers", [1, 2])
def test_installed_extension_renders(repo_root, tmp_path, extension_zips, python_without_embreex, workers):
    resources = tmp_path / "user"
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(resources))
    env.pop("PYTHONPATH", None)
    out = tmp_path / "installed.exr"
    proc = subprocess.run([str(python_without_embreex), "-c", INSTALL_AND_RENDER, str(extension_zips[ZIP]),
                           str(repo_root / "sample_blends" / "cornell_box.blend"), str(out), str(workers)],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    result = json.loads(proc.stdout.split("RESULT ", 1)[1].splitlines()[0])
    assert result["engine"] == "AMCMCPPM"
    assert result["module"].startswith(str(resources / "extensions" / "user_default" / "amcmcppm"))
    site = resources / "extensions" / ".local" / "lib" / "python3.11" / "site-packages"
    assert result["embreex"].startswith(str(site)), "embreex must come from the extension's wheel"
    img = bs.read_exr(out)
    assert img.shape == (25, 25, 4) and np.isfinite(img).all() and img[..., :3].mean() > 0
