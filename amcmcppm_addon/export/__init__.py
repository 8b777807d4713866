"""The only code that reads depsgraph data: Blender scene -> ``core.Scene`` and ``core.RenderSettings``.

``scene.py`` drives the export; one module per data type does the conversion
(``mesh``, ``materials``, ``lights``, ``camera``, ``world``, ``settings``).
"""
from .scene import ExportedScene, export_scene
from .settings import parse_snapshot_times, render_settings_from

__all__ = ["ExportedScene", "export_scene", "render_settings_from", "parse_snapshot_times"]
