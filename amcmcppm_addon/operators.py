"""Operators: export the scene as the core sees it, for replaying outside Blender.

``python -m core render scene.npz --output out.exr`` renders such a file with the
core alone (like Cycles' standalone XML app), which makes exporter and core
problems reproducible without Blender.
"""
import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

from .export import export_scene


class AMCMCPPM_OT_export_scene(bpy.types.Operator, ExportHelper):
    """Save the scene as the AMCMCPPM core receives it (arrays in a .npz file)"""

    bl_idname = "amcmcppm.export_scene"
    bl_label = "Export Core Scene (.npz)"
    filename_ext = ".npz"
    filter_glob: StringProperty(default="*.npz", options={'HIDDEN'})

    def execute(self, context):
        # The viewport depsgraph: viewport visibility and modifier levels apply.
        exported = export_scene(context.evaluated_depsgraph_get())
        for msg in exported.warnings:
            self.report({'WARNING'}, msg)
        exported.scene.save(self.filepath)
        self.report({'INFO'}, f"Saved {exported.scene.triangle_count:,} triangles and "
                              f"{exported.scene.lights.count} lights to {self.filepath}")
        return {'FINISHED'}


classes = (AMCMCPPM_OT_export_scene,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
