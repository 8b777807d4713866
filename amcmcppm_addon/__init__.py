"""Everything of the AMCMCPPM extension that touches Blender (the Cycles add-on split).

``properties`` (scene.amcmcppm) -> ``ui`` (panels) -> ``operators`` -> ``engine``
(the RenderEngine); ``export/`` reads depsgraphs into ``core.Scene``;
``result`` writes images into render results; ``outputs`` writes optional
statistics and snapshot files.  No module keeps mutable state: everything a
render needs lives in the objects of that render.
"""
import bpy

from . import engine, operators, properties, ui

classes = (engine.AMCMCPPMRenderEngine,)


def register():
    properties.register()
    ui.register()
    operators.register()
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    operators.unregister()
    ui.unregister()
    properties.unregister()
