"""Fixtures for the Blender-side tests: the real ``bpy`` module, the add-on registered once.

The add-on's modules use relative imports (``from ..core import ...``), so the
repository root is loaded as a package named ``amcmcppm`` (as Blender loads the
extension as ``bl_ext.<repo>.amcmcppm``).  Registration survives
``read_factory_settings`` (``shared/docs/blender.md`` 4), so each test starts from
an empty factory scene without re-registering.
"""
from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = "amcmcppm"

import bpy  # noqa: E402,F401  (imported before blender_scenes, whose bmesh needs it)

sys.path.insert(0, str(Path(__file__).resolve().parent))
import blender_scenes  # noqa: E402


def load_package():
    """The repository root as the package ``amcmcppm`` (imported once per process)."""
    if PACKAGE in sys.modules:
        return sys.modules[PACKAGE]
    spec = importlib.util.spec_from_file_location(PACKAGE, ROOT / "__init__.py",
                                                  submodule_search_locations=[str(ROOT)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = module
    spec.loader.exec_module(module)
    return module


load_package()       # importable at collection time (engine subclasses in tests); registered below


def pytest_collection_modifyitems(items):
    here = Path(__file__).resolve().parent
    for item in items:
        if here in Path(str(item.fspath)).resolve().parents:
            item.add_marker(pytest.mark.blender)


@pytest.fixture(scope="session")
def addon():
    """The registered add-on package; unregistered at the end of the session."""
    pkg = load_package()
    pkg.register()
    yield pkg
    pkg.unregister()


@pytest.fixture
def scene(addon):
    """An empty factory scene with the AMCMCPPM engine and fast settings."""
    return blender_scenes.empty_scene()


@pytest.fixture(scope="session")
def repo_root():
    return ROOT


@pytest.fixture(scope="session")
def python_env():
    """Environment for subprocesses running ``python render.py`` with this interpreter."""
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    return env
