"""The world -> ``core.World``: a background radiance by direction.

The world's Cycles output is followed to a Background (or Emission) node and its
Color x Strength is used, as Cycles does for a constant background; a world
without nodes uses ``world.color``.  The view layer's world override wins over
the scene's world.  An Environment Texture (equirectangular) on the Background colour
becomes the world's image as it is, turned by a Mapping node's rotation on its vector.  Any
other colour that varies with the direction (texture and colour nodes of ``procedural.py`` on
the world's direction: an environment moved or mixed, a gradient sky...) is evaluated at the
pixel centres of an equirectangular image (``BAKE_WIDTH`` wide, or as wide as the largest
environment image in it, up to ``BAKE_MAX_WIDTH``) that becomes the world's image.  A Sky
Texture (``core/sky.py``) is baked so without its sun disc, which becomes a sun light of the
disc's direction, size and irradiance (times the Background's strength) when the sky is the
Background's colour itself; a disc that other nodes change is left out with a warning.

World > Ray Visibility > Camera off makes what camera rays see past the scene black (``World.camera``);
Diffuse, Glossy, Transmission and Volume Scatter off keep the world's light (its photons, and its
sun disc's) from those rays as Cycles' excluded lights (``World.exclude``), and camera paths that
leave a mirror or a glass then see black past the scene.

The world's Volume (Volume Absorption, Volume Scatter, Principled Volume, as a material's)
fills all space outside the meshes' volumes, unbounded as in Cycles: the sun and the world's
own light then reach nothing in the channels it attenuates (``export_scene`` warns).

World > Light Group (``world.lightgroup``, a name of the view layer's Light Groups): the world's
light and its sky's sun disc belong to that group (``World.group``, the sun's ``Lights.group``), as
in Cycles, where the sun disc is part of the background; a name the view layer does not list is
no group.

World > Mist Pass (start, depth, falloff: ``world.mist_settings``) shapes the Mist pass
(``World.mist_start``, ``mist_depth``, ``mist_falloff``); without a world, Cycles' film's own
(``NO_WORLD_MIST``: from the camera over 100 m, linear; not a new world's 5 m, 25 m, quadratic).
"""
from __future__ import annotations

import numpy as np

from ...core import procedural, sky
from ...core.environment import equirectangular_directions
from ...core.scene import SUN, VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION, World
from .lights import light_exclude, light_group_of, light_record
from .materials import NodeWalker
from .procedural import view_layer_owners

BAKE_WIDTH = 1024          # equirectangular image of a procedural world (height: half)
BAKE_MAX_WIDTH = 4096
# Blender's mist falloff -> the power of the mist's rise (``World.mist_falloff``), as Cycles' film.
MIST_FALLOFF = {"QUADRATIC": 2.0, "LINEAR": 1.0, "INVERSE_QUADRATIC": 0.5}
# The mist of a scene without a world, as Cycles' (its film's defaults: the Mist pass is the distance
# over 100 m; measured against Cycles 5.0).
NO_WORLD_MIST = {"mist_start": 0.0, "mist_depth": 100.0, "mist_falloff": 1.0}


def export_world(depsgraph, textures, log, camera=None, light_groups=None):
    """(``core.World``, list of light records of ``lights.export_light``'s form: a sky's sun disc).
    ``camera``: the scene's ``core.Camera``, for programs of the view (Window, Camera coordinates);
    ``light_groups``: {name: index} of the view layer's light groups (``lights.light_group_index``)."""
    scene = depsgraph.scene_eval
    world = depsgraph.view_layer_eval.world_override or scene.world
    transparent = bool(scene.render.film_transparent)
    if world is None:
        return World(color=np.zeros(3, np.float32), film_transparent=transparent, **NO_WORLD_MIST), []
    walker = NodeWalker(world.name, textures, layer_owners=view_layer_owners(depsgraph))
    color = walker.world_color(world)
    if walker.notes:
        log.warning(f"world '{world.name}': " + "; ".join(walker.notes))
    out, lights = _background(walker, color, textures, world.name, log, camera)
    out.film_transparent = transparent
    if walker.medium is not None:
        absorption, scattering, g, _, (phase, params) = walker.medium    # (emission noted, left out)
        out.volume_absorption = absorption.astype(np.float32)
        out.volume_scattering = scattering.astype(np.float32)
        out.volume_anisotropy = float(g)
        out.volume_phase, out.volume_phase_params = int(phase), np.asarray(params, np.float32)
    if walker.camera_walker is not None:
        out.camera, _ = _background(walker.camera_walker, walker.camera_color, textures, world.name, log,
                                    camera)
    _ray_visibility(world, out, lights)
    _mist(world, out)
    out.group = (light_groups or {}).get(light_group_of(world), -1)
    for rec in lights:
        rec["group"] = out.group
    return out, lights


def _mist(world, out):
    """World > Mist Pass into ``out`` (``World.mist_start``, ``mist_depth``, ``mist_falloff``)."""
    mist = getattr(world, "mist_settings", None)
    if mist is None:
        return
    out.mist_start = float(mist.start)
    out.mist_depth = float(mist.depth)
    out.mist_falloff = MIST_FALLOFF.get(mist.falloff, out.mist_falloff)


def _ray_visibility(world, out, lights):
    """World > Ray Visibility: Camera off makes camera rays see black past the scene (``out.camera``);
    the other boxes keep the world's light from their rays (``out.exclude``).  The sun disc's lights
    ``lights`` follow both."""
    visibility = getattr(world, "cycles_visibility", None)
    if visibility is None:
        return
    hidden = 0 if visibility.camera else VISIBLE_CAMERA
    if hidden:
        out.camera = World(color=np.zeros(3, np.float32))
    out.exclude = light_exclude(visibility)
    # (EXCLUDE_GLOSSY and EXCLUDE_TRANSMISSION are the bits of the rays that then see nothing)
    hidden |= out.exclude & (VISIBLE_GLOSSY | VISIBLE_TRANSMISSION)
    for rec in lights:
        rec["visibility"] &= ~hidden
        rec["exclude"] |= out.exclude


def _background(walker, color, textures, world_name, log, camera=None):
    """(``core.World`` of what a world walker found, sun-disc light records): its colour times its
    environment image, or the bake of its program of the direction; a program that reads the view
    (Window or Camera coordinates: a backplate) is also kept as it is, for camera rays
    (``World.program``)."""
    color = np.nan_to_num(np.maximum(np.asarray(color, np.float64), 0.0))
    texture = program = None
    if walker.world_texture is not None:
        texture = np.maximum(textures.images[walker.world_texture], 0.0)
    lights = []
    if walker.world_texture is None and walker.world_program is not None:
        texture = bake_world(walker.world_program, textures.images, camera)
        lights = sun_disc_lights(walker.world_program, color, world_name, log)
        if camera is not None and procedural.attributes_used(walker.world_program) & set(procedural.VIEW):
            program = walker.world_program
    return World(color=color.astype(np.float32), texture=texture, program=program,
                 texture_rotation=walker.world_rotation if texture is not None else None), lights


def sun_disc_lights(program, strength, world_name, log):
    """A sun light record for the disc of a Sky Texture that is the world's colour, times
    ``strength`` (3,); none (with a warning) for discs of skies that other nodes change."""
    if program["op"] == "sky" and program.get("sun_disc"):
        disc = sky.sun_disc(sky_type=program["sky_type"], sun_disc=True, sun_size=program["sun_size"],
                            sun_intensity=program["sun_intensity"], sun_elevation=program["sun_elevation"],
                            sun_rotation=program["sun_rotation"], altitude=program["altitude"],
                            air_density=program["air_density"], aerosol_density=program["aerosol_density"],
                            ozone_density=program["ozone_density"])
        if disc is None:
            return []
        power = np.maximum(disc["irradiance"] * strength, 0.0)
        if not power.any():
            return []
        # Part of the world: seen by the camera, in mirrors and through glass.
        visibility = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION
        return [light_record(np.zeros(3), -disc["direction"], visibility, kind=SUN,
                             sun_angle=float(disc["angle"]), power=power)]
    if any(n["op"] == "sky" and n.get("sun_disc") and n["sky_type"] != "PREETHAM"
           for n in procedural.nodes(program)):
        log.warning(f"world '{world_name}': the sun disc of a Sky Texture that other nodes change is "
                    "left out (the sky itself is kept)")
    return []


def bake_world(program, images, camera=None):
    """(H, W, 3) float32 equirectangular image of ``program`` (a function of the direction, and of
    ``camera``'s view where it reads Window or Camera coordinates) in the core's layout, evaluated at
    the pixel centres."""
    widths = [images[n["texture"]].shape[1] for n in procedural.nodes(program) if n["op"] == "environment"]
    width = int(min(max([BAKE_WIDTH, *widths]), BAKE_MAX_WIDTH))
    height = width // 2
    dirs = equirectangular_directions(width, height).reshape(-1, 3)
    rgb = procedural.evaluate(program, procedural.DirectionAttributes(dirs, camera), images)
    if rgb.ndim == 1:
        rgb = np.repeat(rgb[:, None], 3, axis=1)
    # Radiance, not an albedo: no upper bound (an HDR sun), but finite and non-negative.
    rgb = np.nan_to_num(np.maximum(rgb, 0.0), nan=0.0, posinf=0.0)
    return rgb.reshape(height, width, 3).astype(np.float32)
