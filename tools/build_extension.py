"""Build the installable Blender extension zips (``make extension``).

    python tools/build_extension.py [--output-dir dist] [--no-split]

1. Download the wheels the manifest lists (``wheels = [...]`` in
   ``blender_manifest.toml``: embreex for Blender's Python 3.11 on Linux x64,
   Windows x64 and macOS arm64) with ``pip download --only-binary=:all: --no-deps``
   into ``build/wheels`` (kept as a cache).  NumPy is never bundled: Blender has it.
2. Stage exactly the extension's files (root ``__init__.py``, the manifest,
   ``amcmcppm_addon/``, ``core/``, the wheels) in ``build/extension``.
3. Run Blender's own builder (``blender_ext.py build``, shipped inside the bpy
   package) with ``--split-platforms``: one zip per platform, each with its wheel.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE_FILES = ("__init__.py", "blender_manifest.toml")
PACKAGE_DIRS = ("amcmcppm_addon", "core")


def blender_ext_cli() -> Path:
    """Path of Blender's extension command line tool inside the installed bpy package."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise SystemExit("build_extension.py: error: the bpy module is not installed (pip install bpy)")
    base = Path(spec.origin).parent
    for candidate in (base / "5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py",
                      *base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py")):
        if candidate.is_file():
            return candidate
    raise SystemExit(f"build_extension.py: error: blender_ext.py not found under {base}")


def manifest_wheels(manifest=ROOT / "blender_manifest.toml"):
    """Wheel file names listed in the manifest."""
    with open(manifest, "rb") as f:
        return [Path(w).name for w in tomllib.load(f).get("wheels", [])]


def download_wheels(names, cache: Path):
    """Make sure every wheel in ``names`` is in ``cache``; download the missing ones."""
    cache.mkdir(parents=True, exist_ok=True)
    for name in names:
        if (cache / name).is_file():
            continue
        dist, version, python_tag, _abi, platform = name[:-len(".whl")].split("-")
        cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--only-binary=:all:", "--no-deps",
               "--python-version", python_tag.removeprefix("cp"), "--platform", platform.split(".")[0],
               "--dest", str(cache), f"{dist}=={version}"]
        subprocess.run(cmd, check=True)
        if not (cache / name).is_file():
            raise SystemExit(f"build_extension.py: error: pip did not produce {name} "
                             f"(got {sorted(p.name for p in cache.iterdir())})")


def stage(dest: Path, wheel_cache: Path, wheels):
    """Copy the extension's files and wheels into an empty ``dest``."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for name in PACKAGE_FILES:
        shutil.copy2(ROOT / name, dest / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".*")
    for name in PACKAGE_DIRS:
        shutil.copytree(ROOT / name, dest / name, ignore=ignore)
    (dest / "wheels").mkdir()
    for name in wheels:
        shutil.copy2(wheel_cache / name, dest / "wheels" / name)


def build(source: Path, output_dir: Path, split=True):
    """Run Blender's builder; return the zips of this id and version in ``output_dir``."""
    output_dir.mkdir(parents=True, exist_ok=True)
    with open(source / "blender_manifest.toml", "rb") as f:
        manifest = tomllib.load(f)
    cmd = [sys.executable, str(blender_ext_cli()), "build", "--source-dir", str(source),
           "--output-dir", str(output_dir)]
    if split:
        cmd.append("--split-platforms")
    subprocess.run(cmd, check=True)
    return sorted(output_dir.glob(f"{manifest['id']}-{manifest['version']}*.zip"))


def main(argv=None):
    p = argparse.ArgumentParser(prog="build_extension.py", description=__doc__.splitlines()[0])
    p.add_argument("--output-dir", default=str(ROOT / "dist"))
    p.add_argument("--build-dir", default=str(ROOT / "build"), help="staging area")
    p.add_argument("--wheel-cache", default=str(ROOT / "build" / "wheels"), help="downloaded wheels")
    p.add_argument("--no-split", action="store_true", help="one zip with every platform's wheels")
    args = p.parse_args(argv)
    build_dir = Path(args.build_dir)
    wheels = manifest_wheels()
    cache = Path(args.wheel_cache)
    download_wheels(wheels, cache)
    staged = build_dir / "extension"
    stage(staged, cache, wheels)
    zips = build(staged, Path(args.output_dir), split=not args.no_split)
    for z in zips:
        print(f"{z} ({os.path.getsize(z) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
