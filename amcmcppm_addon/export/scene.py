"""Depsgraph -> ``core.Scene``: one pass over the object instances, then one module per data type.

``export_scene`` is the only entry point; it never reads ``bpy.context`` (the
render depsgraph carries the view layer, the evaluated scene and its objects),
so it runs the same inside ``RenderEngine.render`` and from tests or operators
with a viewport depsgraph.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ...core.accel import EMBREE_REACH
from ...core.cryptomatte import name_id
from ...core.scene import SUN, Scene
from .camera import export_camera
from .lights import (build_lights, export_light, instance_group, is_portal, light_exclude, light_group_index,
                     portal_frame, ray_visibility, unlisted_groups)
from .linking import LightLinking
from .materials import MaterialExporter
from .mesh import GeometryCollector
from .procedural import view_layer_owners
from .world import export_world


class ExportLog:
    """Warnings and info messages of one export, each message once, in order."""

    def __init__(self):
        self.warnings = {}
        self.infos = {}

    def warning(self, msg):
        self.warnings.setdefault(msg, None)

    def info(self, msg):
        self.infos.setdefault(msg, None)


@dataclass
class ExportedScene:
    """The core scene plus what the engine reports about the export."""

    scene: Scene
    warnings: list = field(default_factory=list)
    infos: list = field(default_factory=list)
    seconds: float = 0.0            # wall time of the export
    instances: int = 0              # geometry instances exported
    meshes: int = 0                 # distinct meshes read
    # Cryptomatte's manifests: {"crypto_object" / "crypto_material" / "crypto_asset": {name: hash
    # hex}} of the kinds the view layer asks for (``core.cryptomatte``)
    cryptomatte_manifests: dict = field(default_factory=dict)

    @property
    def is_empty(self) -> bool:
        """Nothing to render: no triangles, no lights and a black world."""
        s = self.scene
        return s.triangle_count == 0 and s.lights.count == 0 and not np.any(s.world.color)


# The view layer's pass boxes whose core data passes read geometry that only some materials need
# otherwise (``engine.DATA_PASSES``): the box -> the core's name (``GeometryCollector``'s ``passes``).
GEOMETRY_PASSES = {"use_pass_object_index": "object_index", "use_pass_uv": "uv",
                   "use_pass_cryptomatte_object": "crypto_object",
                   "use_pass_cryptomatte_material": "crypto_material",
                   "use_pass_cryptomatte_asset": "crypto_asset"}


def geometry_passes(view_layer) -> frozenset:
    """The core data passes of ``GEOMETRY_PASSES`` that ``view_layer`` asks for."""
    return frozenset(core for box, core in GEOMETRY_PASSES.items() if getattr(view_layer, box, False))


def within_reach(scene, log):
    """``scene`` without its triangles that have a corner at NaN, infinity or a coordinate beyond
    EMBREE_REACH in world space (vertices finite in their object that its transform takes so far:
    float32 holds them no more, and embree leaves such triangles out, as Cycles does), named in a
    warning."""
    far = ~(np.abs(scene.vertices) <= EMBREE_REACH).all(axis=1)         # (NaN fails the test too)
    if not far.any():
        return scene
    out = far.take(scene.triangles).any(axis=1)
    if out.any():
        log.warning(f"{int(out.sum())} of the scene's {len(out)} triangles have a corner beyond "
                    f"{EMBREE_REACH:.3g} or at infinity in world space (an object moved, turned or scaled "
                    "that far): they are left out, as Cycles leaves them")
    vertices = scene.vertices.copy()
    vertices[far] = 0.0                             # (no triangle uses them now)
    generated = scene.generated_vertices
    if generated is not None:
        generated = generated.copy()
        generated[far] = 0.0
    return scene.replace(vertices=vertices, generated_vertices=generated).take_triangles(~out)


def export_scene(depsgraph, camera_object=None, resolution=None, border=None, camera=None,
                 view=None) -> ExportedScene:
    """Export everything ``depsgraph`` shows for its view layer.

    camera_object : the camera to render through (default: the scene camera).
    view : a ``camera.CameraView`` of Stereoscopy to render through that camera (its eye), or None.
    resolution : (width, height) after the resolution percentage (default: the scene's).
    border : (x_min, x_max, y_min, y_max) render border, y from the bottom (default: the scene's).
    camera : a ``core.Camera`` to render through instead of a camera object (the 3D viewport's
        view, ``Camera.from_view``).
    """
    t0 = time.perf_counter()
    log = ExportLog()
    view_layer = depsgraph.view_layer_eval
    materials = MaterialExporter(log, view_layer_owners(depsgraph),
                                 aovs={aov.name: aov.type for aov in view_layer.aovs if aov.name})
    # Light and shadow linking (receiver and blocker collections), each None when unused.
    linking = (LightLinking.from_depsgraph(depsgraph, log, "receiver"),
               LightLinking.from_depsgraph(depsgraph, log, "blocker"))
    # Light groups (View Layer > Light Groups): {name: index of Scene.light_groups}, from the original
    # view layer (adding a group does not tag the depsgraph: an evaluated one may not have it yet).
    groups = light_group_index(depsgraph.view_layer)
    for name, owners in (unlisted_groups(depsgraph, groups) if groups else {}).items():
        named = ", ".join(sorted(owners)[:3]) + (" ..." if len(owners) > 3 else "")
        log.info(f"light group '{name}' of {named} is not in the view layer's Light Groups: its light is "
                 "in no Combined_ pass")
    collector = GeometryCollector(materials, log, material_override=view_layer.material_override,
                                  linking=linking, frame=depsgraph.scene_eval.frame_current_final,
                                  passes=geometry_passes(view_layer), light_groups=groups,
                                  hair=view_layer.use_strand, render=depsgraph.mode == "RENDER")
    light_records, light_collections, portals = [], [], []
    for inst in depsgraph.object_instances:
        if inst.object.type == "LIGHT" and is_portal(inst.object.data):
            portal = portal_frame(inst.object.data, np.array(inst.matrix_world, np.float64))
            if portal is None:
                log.warning(f"light portal '{inst.object.name}' has no area; left out")
            else:
                portals.append(portal)
        elif inst.object.type == "LIGHT":
            rec = export_light(inst.object.data, np.array(inst.matrix_world, np.float64),
                               inst.object.name, log, ray_visibility(inst.object))
            if rec is not None:
                rec["exclude"] = light_exclude(inst.object)
                rec["group"] = instance_group(inst, groups)
                light_records.append(rec)
                # (read here: the iterator reuses its instance objects)
                light_collections.append([-1 if k is None else k.collection(inst.object) for k in linking])
        else:
            collector.add(inst)
    geometry = collector.finish()
    if camera is None:
        camera = export_camera(depsgraph, camera_object, resolution, border, log, view)
    world, world_lights = export_world(depsgraph, materials.textures, log, camera, groups)
    if portals:
        # (Cycles' light portals guide the photons from afar through the windows: Focus.through)
        world.portals = np.array([frame for frame, _ in portals])
        world.portal_disks = np.array([disk for _, disk in portals])
    if depsgraph.scene_eval.render.use_motion_blur:
        log.warning("motion blur is not supported: the frame renders at its own instant")
    sets = {}         # the scene's per-triangle sets and emitter links
    names = (("links", "receiver_sets", "emitter_links", "emitter_collections"),
             ("shadow_links", "blocker_sets", "emitter_shadow_links", "shadow_collections"))
    for i, (kind, (light_key, set_key, links_key, collections_key)) in enumerate(zip(linking, names)):
        if kind is None:
            continue
        for rec, link in zip(light_records, kind.links([c[i] for c in light_collections])):
            rec[light_key] = link
        if getattr(geometry, set_key) is not None:
            sets[set_key] = getattr(geometry, set_key)
            sets[links_key] = kind.links(getattr(geometry, collections_key))
    for rec in light_records:
        if not rec.pop("casts_shadow", True):
            rec["shadow_links"] = np.uint64(0)           # Cast Shadow off: no blocker set shadows it
    lights = build_lights(light_records + world_lights)
    if world.has_volume and (np.any(world.color) or world.texture is not None or (lights.kind == SUN).any()):
        log.warning("the world's volume fills all space, so (as in Cycles) the sun and the world's light "
                    "do not get through it in the colours it attenuates; light the fog with point, spot or "
                    "area lights or emitters")
    if materials.count == 0:
        materials.default_id()
    built = materials.build()
    crypto, manifests = None, {}
    if geometry.cryptomatte is not None:
        # Cryptomatte: the material's id of each triangle between its object's and asset's.
        names = materials.cryptomatte_names()
        hashed = [name_id(name) for name in names]
        material = np.array([h[0] for h in hashed], np.float32).take(geometry.material_ids)
        crypto = np.column_stack([geometry.cryptomatte[:, 0], material, geometry.cryptomatte[:, 1]])
        used = np.unique(geometry.material_ids)
        manifests = {**geometry.crypto_names, "crypto_material": {names[i]: hashed[i][1] for i in used}}
        manifests = {k: v for k, v in manifests.items() if k in collector.passes}   # (those asked for)
    scene = Scene(vertices=geometry.vertices, triangles=geometry.triangles,
                  material_ids=geometry.material_ids, materials=built, lights=lights,
                  camera=camera, world=world, shading_normals=geometry.shading_normals, uvs=geometry.uvs,
                  tangents=geometry.tangents, vertex_colors=geometry.colors, attributes=geometry.attributes,
                  object_ids=geometry.object_ids,
                  object_from_world=geometry.object_from_world, texture_spaces=geometry.texture_spaces,
                  generated_vertices=geometry.generated_vertices,
                  object_info=geometry.object_info, object_attributes=geometry.object_attributes,
                  triangle_visibility=geometry.triangle_visibility, emitter_exclude=geometry.emitter_exclude,
                  textures=materials.textures.images, cryptomatte_ids=crypto,
                  light_groups=tuple(groups), emitter_group=geometry.emitter_group, **sets)
    scene = within_reach(scene, log)
    return ExportedScene(scene=scene.validate(), warnings=list(log.warnings), infos=list(log.infos),
                         seconds=time.perf_counter() - t0, instances=geometry.instances,
                         meshes=geometry.meshes, cryptomatte_manifests=manifests)

