"""Blender lights -> ``core.Lights``, in Cycles' units.

Follows Cycles' light sync (``intern/cycles/blender/light.cpp``) and its
conversion to emitted quantities (``intern/cycles/scene/light.cpp``), see
``shared/docs/blender.md`` section 3:

* strength S = colour x (blackbody colour if ``use_temperature``) x energy x 2^exposure,
  watts (W/m^2 for the sun);
* point and spot: a sphere of radius ``shadow_soft_size`` (not scaled by the object)
  with radiance S / (4 pi^2 r^2) (intensity S / (4 pi) when r = 0); the spot cone
  masks it with Cycles' smoothstep blend without concentrating the power;
* area: one-sided towards the object's -Z, extent ``size`` x ``size_y`` (square and
  disk use ``size`` twice) along the object's X and Y axes *including the object
  scale*, radiance S / (pi A) with A = len_u len_v (x pi/4 for disk and ellipse),
  narrowed by ``spread`` as Cycles' soft box does;
* sun: irradiance S along the object's -Z over a cone of angular diameter ``angle``.

Ray visibility comes from the object (``visible_camera``, ``visible_glossy``,
``visible_transmission``): by default Cycles shows lights in mirrors and through glass but
not to camera rays, and so does the core.  Its Diffuse, Glossy, Transmission and Volume Scatter
boxes off also keep the light from those rays (:func:`light_exclude`, ``Lights.exclude``): a light
without Glossy makes no highlights, one without Diffuse lights only glossy surfaces.  A point or
spot light with Soft Falloff (the default) is seen as a disk facing the viewer, as Cycles shows it;
without, as a sphere.

A light with Cast Shadow off (``use_shadow``) is shadowed by nothing: its shadow links hold no
blocker set (``Lights.shadow_links`` = 0, the core's shadow linking), so its photons light every
surface along their first flight, as Cycles' unshadowed light samples do.

An area light marked as a Cycles portal (``cycles.is_portal``) emits nothing and is invisible, as
in Cycles, where it guides the sampling of the world through a window: here it becomes one of the
world's portals (:func:`portal_frame`, ``World.portals``), through which the photons from afar (the
world's and the sun's) are aimed, and the world's light samples (``direct_light = "sampled"``).

Light groups (View Layer > Light Groups; Object > Shading > Light Group): a light's
``object.lightgroup`` names its group, whose pass (Cycles' ``Combined_<name>``) holds the light it
sends (``Lights.group``); a name the view layer does not list, or none, is no group.  An instance
without a group of its own takes its instancer's, as Cycles' sync does (:func:`instance_group`).

``normalize = False`` makes Cycles skip the division by the emitting area (or by
the sun's solid angle); the core always divides, so the power is multiplied back.

A light with nodes (``use_nodes``) multiplies its strength by its Emission node's Color times
Strength (:func:`node_factor`: constants, Blackbody included; a texture takes its mean, noted).
An IES Texture on a point, spot or area light's Emission Strength gives it an angular profile
(``Lights.profile``, tabulated by ``ies.py`` as Cycles reads the file) in the light's own frame
(Cycles looks the profile up by the light's Normal coordinate, the direction towards the lit
point); a point or spot light's X and Y axes go to ``axis_u`` and ``axis_v``.  The sun takes the
profile's value along its -Z, the one direction its light has.
"""
from __future__ import annotations

import math

import numpy as np

from ...core.scene import (ALL_LINKS, AREA_DISK, AREA_RECT, EXCLUDE_DIFFUSE, EXCLUDE_GLOSSY, EXCLUDE_SCATTER,
                           EXCLUDE_TRANSMISSION, POINT, SPOT, SUN, VISIBLE_CAMERA, VISIBLE_GLOSSY,
                           VISIBLE_TRANSMISSION, Lights)


def light_strength(light) -> np.ndarray:
    """(3,) float64 Cycles strength of a Light datablock."""
    color = np.array(light.color[:3], np.float64)
    if light.use_temperature:
        color *= np.array(light.temperature_color[:3], np.float64)
    return color * float(light.energy) * 2.0 ** float(light.exposure)


def ray_visibility(obj) -> int:
    """The camera-path rays that see an object (Object > Visibility > Ray Visibility: Camera,
    Glossy, Transmission) as ``Lights.visibility`` bits, which ``Scene.triangle_visibility``
    shares.  A mesh's Diffuse and Volume Scatter boxes concern rays that photons stand in for,
    which always meet it (an emissive mesh's boxes keep its light from those rays,
    :func:`light_exclude`); its Shadow box is ``CASTS_NO_SHADOW`` (``mesh.py``)."""
    return ((VISIBLE_CAMERA if obj.visible_camera else 0) | (VISIBLE_GLOSSY if obj.visible_glossy else 0)
            | (VISIBLE_TRANSMISSION if obj.visible_transmission else 0))


def light_exclude(visibility) -> int:
    """The rays an emitter does not light (``Lights.exclude`` bits) from Blender's Ray Visibility:
    an object's (``visible_diffuse``, ``visible_glossy``, ``visible_transmission``,
    ``visible_volume_scatter``) or a world's ``cycles_visibility`` (``diffuse``, ``glossy``,
    ``transmission``, ``scatter``), as Cycles' SHADER_EXCLUDE_* flags."""
    bits = 0
    for names, bit in ((("visible_diffuse", "diffuse"), EXCLUDE_DIFFUSE),
                       (("visible_glossy", "glossy"), EXCLUDE_GLOSSY),
                       (("visible_transmission", "transmission"), EXCLUDE_TRANSMISSION),
                       (("visible_volume_scatter", "scatter"), EXCLUDE_SCATTER)):
        on = next((getattr(visibility, n) for n in names if hasattr(visibility, n)), True)
        if not on:
            bits |= bit
    return bits


def export_light(light, world_from_light, name, log, visibility=VISIBLE_GLOSSY | VISIBLE_TRANSMISSION):
    """One ``Lights.build``-style field dict for a light object, or None if it emits nothing.

    world_from_light : (4, 4) float64 object matrix (with scale); visibility : bits of
    :func:`ray_visibility`.
    """
    m = np.asarray(world_from_light, np.float64)
    if is_portal(light):
        # (a portal emits nothing and nothing sees it: portal_frame)
        return None
    strength = light_strength(light)
    if not (np.isfinite(strength).all() and np.isfinite(m).all()):
        log.warning(f"light '{name}': its strength or placement is not a finite number (NaN or "
                    "infinite); skipped")
        return None
    if (strength < 0).any():
        log.warning(f"light '{name}' has negative strength, which photon tracing cannot emit; skipped")
        return None
    if not strength.any():
        return None
    profile = None
    if getattr(light, "use_nodes", False) and light.node_tree is not None:
        factor, profile = node_factor(light.node_tree, name, log, light.type != "SUN")
        strength = strength * factor
        if not np.isfinite(strength).all():
            log.warning(f"light '{name}': its nodes make its strength not a finite number; skipped")
            return None
        if not strength.any():
            return None
    position = m[:3, 3]
    direction = _unit(-m[:3, 2], fallback=(0.0, 0.0, -1.0))
    rec = light_record(position, direction, visibility, bool(getattr(light, "use_soft_falloff", True)))
    # Cast Shadow off: nothing shadows it (shadow links to no blocker set; scene.py keeps that over
    # shadow linking's links).
    rec["casts_shadow"] = bool(getattr(light, "use_shadow", True))
    if profile is not None and light.type != "AREA":
        # The light's frame for the profile: its X and Y axes, made orthonormal with -direction
        # (an area light's axes are its half extents, set below).
        x = _unit(m[:3, 0] - (m[:3, 0] @ direction) * direction, fallback=(1.0, 0.0, 0.0))
        rec.update(profile=profile, axis_u=x, axis_v=np.cross(-direction, x))
    elif profile is not None:
        rec.update(profile=profile)
    if light.type in ("POINT", "SPOT"):
        r = max(float(light.shadow_soft_size), 0.0)
        if not light.normalize and r > 0:
            strength = strength * (4.0 * math.pi * r * r)
        rec.update(kind=POINT, radius=r, power=strength)
        if light.type == "SPOT":
            rec.update(kind=SPOT, spot_angle=float(light.spot_size),
                       spot_blend=float(np.clip(light.spot_blend, 0.0, 1.0)))
            scale = np.linalg.norm(m[:3, :3], axis=0)
            if np.ptp(scale) > 1e-6 * scale.max():
                log.warning(f"spot light '{name}': non-uniform object scale does not change the cone here")
    elif light.type == "AREA":
        size_u = float(light.size)
        size_v = float(light.size_y) if light.shape in ("RECTANGLE", "ELLIPSE") else size_u
        axis_u = m[:3, 0] * (size_u / 2)
        axis_v = m[:3, 1] * (size_v / 2)
        disk = light.shape in ("DISK", "ELLIPSE")
        area = 4.0 * np.linalg.norm(axis_u) * np.linalg.norm(axis_v) * (math.pi / 4 if disk else 1.0)
        if area <= 0:
            log.warning(f"area light '{name}' has zero size; skipped")
            return None
        if not light.normalize:
            strength = strength * area
        rec.update(kind=AREA_DISK if disk else AREA_RECT, axis_u=axis_u, axis_v=axis_v, power=strength,
                   spread=float(np.clip(light.spread, 0.0, math.pi)))
    elif light.type == "SUN":
        angle = float(np.clip(light.angle, 0.0, math.pi))
        if not light.normalize and angle > 0:
            strength = strength * (math.pi * math.sin(angle / 2) ** 2)
        rec.update(kind=SUN, sun_angle=angle, power=strength)
    else:
        log.warning(f"light '{name}' of type {light.type} is not supported; skipped")
        return None
    return rec


def is_portal(light) -> bool:
    """Whether the light is an area light marked as a Cycles portal."""
    return light.type == "AREA" and bool(getattr(getattr(light, "cycles", None), "is_portal", False))


def portal_frame(light, world_from_light):
    """((3, 3) centre and half extents u, v with u x v along the light's -Z, into the scene; is it
    an ellipse) of a portal (:func:`is_portal`), for ``World.portals``; None if it has no area."""
    m = np.asarray(world_from_light, np.float64)
    size_u = float(light.size)
    size_v = float(light.size_y) if light.shape in ("RECTANGLE", "ELLIPSE") else size_u
    u, v = m[:3, 0] * (size_u / 2), m[:3, 1] * (size_v / 2)
    cross = np.cross(u, v)
    if not np.linalg.norm(cross) > 0 or not np.isfinite(m).all():
        return None
    if cross @ -m[:3, 2] < 0:
        u, v = v, u             # (a mirrored object: the light still faces its -Z)
    return np.array([m[:3, 3], u, v]), light.shape in ("DISK", "ELLIPSE")


def node_factor(tree, name, log, profiles=True):
    """((3,) factor, profile table or None) of a light's node tree: Color x Strength of the
    Emission node feeding its output (Cycles), 0 with nothing linked; other shaders are noted and
    count as 1.  An IES Texture on the Strength gives its own Strength as the factor and, with
    ``profiles`` (point, spot and area lights), the file's profile (``ies.tabulate``); without
    (the sun), the factor takes the profile's value along the light's -Z, as in Cycles."""
    from .materials import NodeWalker, Textures
    walker = NodeWalker(f"light '{name}'", Textures(log))
    out = tree.get_output_node("CYCLES")
    src, _, stack = walker.source(out.inputs["Surface"], ()) if out is not None else (None, None, ())
    factor, profile = np.ones(3), None
    if out is None:
        walker.note("no light output node; using its colour and power")
    elif src is None:
        factor = np.zeros(3)
    elif src.node.bl_idname == "ShaderNodeEmission" and not src.node.mute:
        color, source = walker.color(src.node.inputs["Color"], stack)
        if isinstance(source, dict) or source >= 0:
            walker.note("a texture on its Emission Color takes its mean")
        ies, ies_stack = _ies_node(walker, src.node.inputs["Strength"], stack)
        if ies is None:
            strength = walker.value(src.node.inputs["Strength"], stack)
        else:
            strength, profile = _ies_profile(walker, ies, ies_stack)
            if not profiles and profile is not None:
                # The sun's light has one direction, the light's -Z (v = 0, h = pi): one factor.
                strength, profile = strength * float(profile[0, (profile.shape[1] - 1) // 2]), None
        factor = np.maximum(color * strength, 0.0)
    else:
        walker.unsupported(src.node, "in a light's nodes; using its colour and power")
    if walker.notes:
        log.warning(f"light '{name}': " + "; ".join(walker.notes))
    return factor, profile


def _ies_node(walker, sock, stack):
    """(IES Texture node, its stack) whose Fac feeds ``sock`` directly, or (None, None)."""
    src, _, stack = walker.source(sock, stack)
    if src is None or src.node.bl_idname != "ShaderNodeTexIES" or src.node.mute:
        return None, None
    return src.node, stack


def _ies_profile(walker, node, stack):
    """(strength, table or None) of an IES Texture node: its Strength and the profile of its
    file (internal text or external path); a file that cannot be read is noted and lights
    evenly."""
    import bpy
    from . import ies
    strength = walker.value(node.inputs["Strength"], stack)
    if walker.linked(node.inputs["Vector"], stack):
        walker.note(f"IES Texture '{node.name}': a linked Vector is ignored (the light's own frame)")
    try:
        if node.mode == "INTERNAL":
            if node.ies is None:
                raise ies.IESError("no text datablock")
            text = node.ies.as_string()
        else:
            with open(bpy.path.abspath(node.filepath), encoding="utf-8", errors="replace") as f:
                text = f.read()
        return strength, ies.tabulate(text)
    except (OSError, ValueError, IndexError) as e:          # (ies.IESError is a ValueError)
        walker.note(f"IES Texture '{node.name}': cannot read its profile ({e}); the light shines evenly")
        return strength, None


def light_record(position, direction, visibility, soft_falloff=True, **fields) -> dict:
    """A light's field dict (``build_lights``): the given fields over neutral defaults."""
    return {"position": position, "direction": direction, "radius": 0.0, "spot_angle": math.pi / 4,
            "spot_blend": 0.0, "sun_angle": 0.0, "axis_u": np.zeros(3), "axis_v": np.zeros(3),
            "visibility": visibility, "soft_falloff": soft_falloff, "spread": math.pi, "profile": None,
            "links": ALL_LINKS, "shadow_links": ALL_LINKS, "exclude": 0, "group": -1, **fields}


def light_group_names(view_layer) -> tuple:
    """The light groups of ``view_layer`` (View Layer > Light Groups), its distinct non-empty names in
    its order: ``Scene.light_groups``, and the ``Combined_<name>`` passes the engine registers.  (An
    evaluated view layer may miss groups added since its depsgraph was evaluated: pass the original,
    ``depsgraph.view_layer``.)"""
    return tuple(dict.fromkeys(lg.name for lg in getattr(view_layer, "lightgroups", ()) if lg.name))


def light_group_index(view_layer) -> dict:
    """{name: index into :func:`light_group_names`} of ``view_layer``'s light groups."""
    return {name: i for i, name in enumerate(light_group_names(view_layer))}


def light_group_of(data) -> str:
    """The ``lightgroup`` name of an object or a world, read from the original datablock: setting it
    does not tag the depsgraph, so an evaluated copy may still hold the name it had before."""
    return (getattr(data, "original", None) or data).lightgroup


def instance_group(inst, groups) -> int:
    """The light group of depsgraph object instance ``inst`` (an index of ``groups``, the
    :func:`light_group_index`; -1: none), as Cycles' sync finds it: its object's ``lightgroup``, or,
    when that is empty, its instancer's (the object whose collection, particles or geometry nodes
    make the instance).  A name the view layer does not list is no group."""
    if not groups:
        return -1
    name = light_group_of(inst.object)
    if not name and inst.is_instance and inst.parent is not None:
        name = light_group_of(inst.parent)
    return groups.get(name, -1)


def unlisted_groups(depsgraph, groups) -> dict:
    """{name: [owners]} of the light groups that objects of ``depsgraph`` or its world name but the
    view layer does not list (``groups``, :func:`light_group_index`, not empty): their light goes to
    no group's pass, as in Cycles, whose field then offers to add the name."""
    out = {}
    world = depsgraph.view_layer_eval.world_override or depsgraph.scene_eval.world
    owners = [(ob.name, light_group_of(ob)) for ob in depsgraph.objects]
    if world is not None:
        owners.append((f"world {world.name}", light_group_of(world)))
    for owner, name in owners:
        if name and name not in groups:
            out.setdefault(name, []).append(owner)
    return out


def build_lights(records) -> Lights:
    """``core.Lights`` from the dicts of :func:`export_light`."""
    n = len(records)
    lights = Lights(kind=np.zeros(n, np.int8), position=np.zeros((n, 3)),
                    direction=np.zeros((n, 3), np.float32), axis_u=np.zeros((n, 3), np.float32),
                    axis_v=np.zeros((n, 3), np.float32), power=np.zeros((n, 3), np.float32),
                    radius=np.zeros(n, np.float32), spot_angle=np.zeros(n, np.float32),
                    spot_blend=np.zeros(n, np.float32), sun_angle=np.zeros(n, np.float32),
                    visibility=np.zeros(n, np.uint8), soft_falloff=np.ones(n, bool),
                    spread=np.full(n, math.pi, np.float32), profile=np.full(n, -1, np.int16),
                    links=np.full(n, ALL_LINKS, np.uint64), shadow_links=np.full(n, ALL_LINKS, np.uint64),
                    exclude=np.zeros(n, np.uint8), group=np.full(n, -1, np.int16))
    tables = []
    for i, rec in enumerate(records):
        for name in Lights.ARRAY_FIELDS:
            if name != "profile":
                getattr(lights, name)[i] = rec[name]
        if rec.get("profile") is not None:
            lights.profile[i] = len(tables)
            tables.append(rec["profile"])
    lights.profiles = np.stack(tables) if tables else None
    return lights


def _unit(v, fallback):
    n = np.linalg.norm(v)
    return v / n if n > 1e-20 else np.asarray(fallback, np.float64)
