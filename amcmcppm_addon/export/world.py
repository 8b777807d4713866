"""The world -> ``core.World``: a constant background radiance.

The world's Cycles output is followed to a Background (or Emission) node and its
Color x Strength is used, as Cycles does for a constant background; a world
without nodes uses ``world.color``.  The view layer's world override wins over
the scene's world.  An Environment Texture (equirectangular) on the Background colour
becomes the world's image, turned by a Mapping node's rotation on its vector (other vector
inputs are ignored with a warning).  Other textures (sky) give one warning and the node's own
colour.
"""
from __future__ import annotations

import numpy as np

from ...core.scene import World
from .materials import NodeWalker


def export_world(depsgraph, textures, log) -> World:
    scene = depsgraph.scene_eval
    world = depsgraph.view_layer_eval.world_override or scene.world
    transparent = bool(scene.render.film_transparent)
    if world is None:
        return World(color=np.zeros(3, np.float32), film_transparent=transparent)
    walker = NodeWalker(world.name, textures)
    color = walker.world_color(world)
    if walker.notes:
        log.warning(f"world '{world.name}': " + "; ".join(walker.notes))
    color = np.nan_to_num(np.maximum(np.asarray(color, np.float64), 0.0))
    texture = None
    if walker.world_texture is not None:
        texture = np.maximum(textures.images[walker.world_texture], 0.0)
    return World(color=color.astype(np.float32), film_transparent=transparent, texture=texture,
                 texture_rotation=walker.world_rotation if texture is not None else None)
