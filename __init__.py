"""AMCMCPPM: the Blender extension's entry point (the repository root is the extension package).

Blender imports this package and calls :func:`register`; pytest imports it too while
collecting, so ``bpy`` is imported only inside the two functions.  Everything that
touches Blender lives in ``amcmcppm_addon/``; the renderer lives in ``core/``.
"""


def register():
    from .amcmcppm_addon import register as register_addon
    register_addon()


def unregister():
    from .amcmcppm_addon import unregister as unregister_addon
    unregister_addon()
