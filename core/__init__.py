"""AMCMCPPM rendering core: NumPy + embreex, no Blender.

Public API::

    from core import Scene, RenderSettings, render
    result = render(scene, RenderSettings(passes=8), on_iteration=None, should_stop=None)
    result.image   # (H, W, 4) float32 linear RGBA, top row first
    result.stats   # one dict per pass (see core.integrator.PASS_STAT_KEYS)

All imports inside this package are relative, so it loads both as ``core`` and as
a sub-package of the Blender extension.
"""
from .scene import (AREA_DISK, AREA_RECT, POINT, SPOT, SUN, Camera, Lights, Materials, Scene,
                    SceneError, World)
from .settings import RenderSettings
from .integrator import RenderResult, render

__all__ = ["Scene", "SceneError", "Materials", "Lights", "Camera", "World", "RenderSettings",
           "RenderResult", "render", "POINT", "SPOT", "AREA_RECT", "AREA_DISK", "SUN"]
