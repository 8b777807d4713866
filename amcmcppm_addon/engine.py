"""The AMCMCPPM RenderEngine: a thin class whose ``render`` runs :func:`render_final`.

One final render of one view layer (``shared/docs/style.md`` 7.4):
``export_scene(depsgraph)`` -> ``core.render(scene, settings, on_iteration, should_stop)``
-> the render result.  Every pass reports statistics and progress; the image is
pushed after passes 1, 3, 7, ... and then about once per second; ``test_break``
is the core's ``should_stop``, so cancelling returns promptly with the image so
far.  Any exception reaches Blender as ``report({'ERROR'})``: it is the only
report that makes ``bpy.ops.render.render`` fail cleanly instead of crashing
when ``write_still`` is set (``shared/docs/blender.md`` 1).  The 3D viewport's Rendered
shading runs through ``view_update`` and ``view_draw`` (``viewport.py``).
"""
from __future__ import annotations

import json
import traceback

import bpy
import numpy as np

from ..core import SceneError
from ..core.cryptomatte import name_id
from ..core.integrator import render as core_render
from ..core.settings import AOV_PREFIX, DATA_PASSES as DATA_PASS_NAMES, LIGHTGROUP_PREFIX
from .export import export_scene, parse_snapshot_times, render_settings_from
from .export.camera import CameraView
from .export.lights import light_group_names
from .outputs import RenderOutputs
from .result import PushSchedule, ResultWriter, progress_fraction, stats_line
from .viewport import ViewportRender


class AMCMCPPMRenderEngine(bpy.types.RenderEngine):
    bl_idname = "AMCMCPPM"
    bl_label = "AMCMCPPM"
    bl_use_preview = False
    bl_use_postprocess = True
    # Keep Blender's shader nodes (Principled BSDF, ...) editable while this engine is active.
    bl_use_shading_nodes_custom = False

    def __init__(self, *args, **kwargs):
        # Blender 5.0 passes arguments to __init__; keep it cheap (it also runs for pass queries).
        super().__init__(*args, **kwargs)
        self.viewport = None        # the 3D viewport's live render (Rendered shading), when drawn

    def __del__(self):
        # (the viewport's engine is freed when the viewport leaves Rendered shading)
        try:
            if self.viewport is not None:
                self.viewport.close()
        except Exception:
            pass

    def render(self, depsgraph):
        report_errors(self, render_final, self, depsgraph)

    def view_update(self, context, depsgraph):
        if self.viewport is not None:
            self.viewport.scene_changed()

    def view_draw(self, context, depsgraph):
        if self.viewport is None:
            self.viewport = ViewportRender()
        try:
            self.viewport.draw(self, context, depsgraph)
        except Exception as exc:        # (never an exception out of a redraw)
            self.viewport.fail(exc)

    def update_render_passes(self, scene=None, renderlayer=None):
        """The passes this engine writes: Combined, the data passes the view layer asks for
        (``DATA_PASSES``, Cryptomatte, Shader AOVs) and a ``Combined_<name>`` pass per light group,
        as Cycles registers them."""
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", 'COLOR')
        for (name, channels, chan_id, kind), owner, prop, _ in DATA_PASSES:
            if asks_for(renderlayer, owner, prop):
                self.register_pass(scene, renderlayer, name, channels, chan_id, kind)
        for prefix, prop, _ in CRYPTO_PASSES:
            if asks_for(renderlayer, "", prop):
                for i in range(crypto_pass_count(renderlayer)):
                    self.register_pass(scene, renderlayer, f"{prefix}{i:02d}", 4, "rgba", 'COLOR')
        for aov in shader_aovs(renderlayer):
            if aov.type == 'VALUE':
                self.register_pass(scene, renderlayer, aov.name, 1, "X", 'VALUE')
            else:
                self.register_pass(scene, renderlayer, aov.name, 4, "RGBA", 'COLOR')
        for name in light_group_names(renderlayer):
            self.register_pass(scene, renderlayer, LIGHTGROUP_PASS + name, 3, "RGB", 'COLOR')


# Blender's passes beside Combined: (name, channels, channel ids, type), the box of the view layer
# that asks for it ("" the view layer's own, "cycles" its Cycles settings: Denoising Data, Volume,
# Shadow Catcher) and the core's data pass it shows (RenderSettings.data_passes).
DENOISING = ("cycles", "denoising_store_passes")
LIGHT_PARTS = ("direct", "indirect", "color")
DATA_PASSES = ((("Depth", 1, "Z", 'VALUE'), "", "use_pass_z", "depth"),
               (("Mist", 1, "Z", 'VALUE'), "", "use_pass_mist", "mist"),
               (("Position", 3, "XYZ", 'VECTOR'), "", "use_pass_position", "position"),
               (("Normal", 3, "XYZ", 'VECTOR'), "", "use_pass_normal", "normal"),
               (("UV", 3, "UVA", 'VECTOR'), "", "use_pass_uv", "uv"),
               (("Object Index", 1, "X", 'VALUE'), "", "use_pass_object_index", "object_index"),
               (("Material Index", 1, "X", 'VALUE'), "", "use_pass_material_index", "material_index"),
               (("Denoising Normal", 3, "XYZ", 'VECTOR'), *DENOISING, "denoising_normal"),
               (("Denoising Albedo", 3, "RGB", 'COLOR'), *DENOISING, "albedo"),
               (("Denoising Depth", 1, "Z", 'VALUE'), *DENOISING, "denoising_depth"),
               # Light passes (View Layer > Passes > Light; core/light_passes.py), Cycles' order:
               # "Diffuse Direct" is the box use_pass_diffuse_direct and the core's diffuse_direct.
               *(((f"{kind.title()} {part.title()}", 3, "RGB", 'COLOR'), "cycles" if kind == "volume" else "",
                  f"use_pass_{kind}_{part}", f"{kind}_{part}")
                 for kind in ("diffuse", "glossy", "transmission", "volume")
                 for part in (LIGHT_PARTS[:2] if kind == "volume" else LIGHT_PARTS)),
               (("Emission", 3, "RGB", 'COLOR'), "", "use_pass_emit", "emission"),
               (("Environment", 3, "RGB", 'COLOR'), "", "use_pass_environment", "environment"),
               (("Ambient Occlusion", 3, "RGB", 'COLOR'), "", "use_pass_ambient_occlusion", "ao"),
               # (Cycles' box under Light > Other: the shadows and light the shadow catchers receive)
               (("Shadow Catcher", 3, "RGB", 'COLOR'), "cycles", "use_pass_shadow_catcher", "shadow_catcher"))


# Cryptomatte (View Layer > Cryptomatte): Blender's pass names' prefix, the box, the core's pass.
# Each pass holds two (id, coverage) levels, as Cycles writes them.
CRYPTO_PASSES = (("CryptoObject", "use_pass_cryptomatte_object", "crypto_object"),
                 ("CryptoMaterial", "use_pass_cryptomatte_material", "crypto_material"),
                 ("CryptoAsset", "use_pass_cryptomatte_asset", "crypto_asset"))


# A light group's pass (View Layer > Light Groups): Blender's name is this and the group's name;
# the core's data pass is LIGHTGROUP_PREFIX and the name.
LIGHTGROUP_PASS = "Combined_"


def shader_aovs(view_layer):
    """The view layer's valid Shader AOVs (View Layer > Shader AOV), whose passes Cycles writes."""
    return [aov for aov in getattr(view_layer, "aovs", ()) if aov.is_valid and aov.name]


def crypto_pass_count(view_layer) -> int:
    """Passes per kind of Cryptomatte: the view layer's Levels in twos (Cycles' count)."""
    return (min(int(getattr(view_layer, "pass_cryptomatte_depth", 6)), 16) + 1) // 2


def asks_for(view_layer, owner, prop):
    """Whether the box ``prop`` of ``view_layer`` (or of its ``owner`` settings) is ticked."""
    holder = getattr(view_layer, owner, None) if owner else view_layer
    return bool(getattr(holder, prop, False))


def data_passes_of(view_layer):
    """The core's ``RenderSettings.data_passes`` for the passes ``view_layer`` asks for."""
    wanted = {core for _, owner, prop, core in DATA_PASSES if asks_for(view_layer, owner, prop)}
    wanted |= {core for _, prop, core in CRYPTO_PASSES if asks_for(view_layer, "", prop)}
    return (tuple(name for name in DATA_PASS_NAMES if name in wanted)
            + tuple(AOV_PREFIX + aov.name for aov in shader_aovs(view_layer))
            + tuple(LIGHTGROUP_PREFIX + name for name in light_group_names(view_layer)))


def pass_images(data, camera, aov_types=None):
    """Blender's pass name -> image of the core's data passes ``data`` (``RenderResult.data``):
    the Denoising Normal in the camera's frame as Cycles' (x right, y up, z into the view) where
    the Normal pass is in world space.  ``camera`` the exported ``core.Camera``; ``aov_types``
    {name: 'COLOR' or 'VALUE'} of the Shader AOVs (a colour AOV is RGBA, its alpha where written; a
    value AOV one channel).  A light group's pass is ``Combined_<name>``."""
    out = {}
    aov_types = aov_types or {}
    for (name, *_), _, _, core in DATA_PASSES:
        if core not in data:
            continue
        image = data[core]
        if name == "Denoising Normal":
            m = np.asarray(camera.world_from_camera, np.float64)[:3, :3]
            axes = m / np.linalg.norm(m, axis=0)
            axes[:, 2] *= -1.0
            image = (image @ axes).astype(np.float32)
        out[name] = image
    for prefix, _, core in CRYPTO_PASSES:
        if core in data:
            pairs = data[core]               # (H, W, 2 levels): two levels a pass
            for i in range(pairs.shape[2] // 4):
                out[f"{prefix}{i:02d}"] = pairs[:, :, 4 * i:4 * i + 4]
    for name, image in data.items():
        if name.startswith(AOV_PREFIX):      # (H, W, 4): the colour and where written, or a value
            aov = name[len(AOV_PREFIX):]
            out[aov] = image if aov_types.get(aov) == 'COLOR' else image[..., 0]
        elif name.startswith(LIGHTGROUP_PREFIX):     # (H, W, 3)
            out[LIGHTGROUP_PASS + name[len(LIGHTGROUP_PREFIX):]] = image
    return out


def crypto_metadata(layer, manifests):
    """{key: value} of the render result's metadata that name the Cryptomatte passes of view layer
    ``layer`` and their manifests (``cryptomatte/<7 hex of the layer's hash>/name``, ``hash``,
    ``conversion``, ``manifest``), as Blender writes them for Cycles."""
    out = {}
    for prefix, _, core in CRYPTO_PASSES:
        if core not in manifests:
            continue
        name = f"{layer}.{prefix}"
        key = f"cryptomatte/{name_id(name)[1][:7]}"
        out[f"{key}/name"] = name
        out[f"{key}/hash"] = "MurmurHash3_32"
        out[f"{key}/conversion"] = "uint32_to_float32"
        out[f"{key}/manifest"] = json.dumps(manifests[core], separators=(",", ":"))
    return out


def report_errors(engine, function, *args):
    """Call ``function(*args)``; any exception becomes ``engine.report({'ERROR'}, ...)``."""
    try:
        function(*args)
    except (SceneError, ValueError) as e:
        traceback.print_exc()
        engine.report({'ERROR'}, f"AMCMCPPM: {e}")
    except Exception as e:
        traceback.print_exc()
        engine.report({'ERROR'}, f"AMCMCPPM: {type(e).__name__}: {e}")


def render_final(engine, depsgraph):
    """Render the view layer of ``depsgraph`` into ``engine``'s result: each view of Stereoscopy
    in turn (through its eye, into its own image, with the whole settings each, as Cycles), or
    the camera's one view.

    ``engine`` is the RenderEngine (or an object forwarding to it): everything this
    function does to Blender goes through its methods.
    """
    scene = depsgraph.scene_eval
    props = scene.amcmcppm
    # (World > Ambient Occlusion > Distance: the Ambient Occlusion pass's, as Cycles')
    world = scene.world
    settings = render_settings_from(props, data_passes=data_passes_of(depsgraph.view_layer),
                                    pass_alpha_threshold=float(depsgraph.view_layer.pass_alpha_threshold),
                                    cryptomatte_levels=2 * crypto_pass_count(depsgraph.view_layer),
                                    ao_distance=(max(float(world.light_settings.distance), 1e-6)
                                                 if world is not None else 10.0))
    for msg in props.light_path_limits()[1]:
        engine.report({'WARNING'}, f"AMCMCPPM: {msg}")
    view_layer = depsgraph.view_layer.name
    views = render_views(engine, scene, view_layer)
    reported = set()
    for index, view in enumerate(views):
        render_view(engine, depsgraph, settings, camera_view(engine, depsgraph, view), (index, len(views)),
                    reported)
        if engine.test_break():
            break


def render_views(engine, scene, layer):
    """The names of the views Blender renders: the render result's views with Stereoscopy on
    (Stereo 3D's left and right, or Multi-View's in use), else ``[None]`` (the camera's one view)."""
    if not scene.render.use_multiview:
        return [None]
    probe = engine.begin_result(0, 0, 1, 1, layer=layer)
    if probe is None:
        return [None]
    names = [v.name for v in probe.views]
    engine.end_result(probe, cancel=True)
    return names or [None]


def camera_view(engine, depsgraph, name):
    """The ``CameraView`` of view ``name`` (its eye's camera matrix and shift, from Blender), made
    the engine's active view; None for the camera's one view (``name`` None)."""
    if name is None:
        return None
    engine.active_view_set(name)
    ob = engine.camera_override or depsgraph.scene_eval.camera
    if ob is None or ob.type != "CAMERA":
        # (the export names a missing camera; an object that is not a camera has no eyes)
        return CameraView(name, np.eye(4), 0.0)
    ob = ob.evaluated_get(depsgraph)
    # (A panoramic camera's Spherical Stereo turns its eyes with each ray's direction in Cycles;
    # here each eye stays where it is for the view straight ahead: named in a warning.)
    return CameraView(name, np.array(engine.camera_model_matrix(ob, use_spherical_stereo=False), np.float64),
                      float(engine.camera_shift_x(ob, use_spherical_stereo=False)))


def render_view(engine, depsgraph, settings, view, of, reported):
    """Export and render one view into its image of ``engine``'s result.  ``view`` a
    ``CameraView`` or None; ``of`` (its index, the number of views); ``reported`` the messages
    already reported (by an earlier view)."""
    scene = depsgraph.scene_eval
    props = scene.amcmcppm
    label = f"view '{view.name}': " if view is not None else ""

    def report(kind, msg):
        if msg not in reported:
            reported.add(msg)
            engine.report({kind}, msg)

    engine.update_stats("", f"{label}Exporting scene")
    exported = export_scene(depsgraph, camera_object=engine.camera_override,
                            resolution=(engine.resolution_x, engine.resolution_y), view=view)
    if view is not None and exported.scene.camera.projection not in ("perspective", "orthographic"):
        report('WARNING', "AMCMCPPM: Stereoscopy with a panoramic camera: each eye sees from where it "
                          "stands for the view ahead (Cycles' Spherical Stereo turns the eyes with the "
                          "view's direction)")
    for msg in exported.infos:
        report('INFO', msg)
    for msg in exported.warnings:
        report('WARNING', msg)
    view_layer = depsgraph.view_layer.name
    tags = {"view_layer": view_layer, "frame": scene.frame_current}
    outputs = RenderOutputs(stats_path=bpy.path.abspath(props.stats_path) if props.stats_path else "",
                            snapshot_times=parse_snapshot_times(props.snapshot_times),
                            snapshot_dir=bpy.path.abspath(props.snapshot_dir) if props.snapshot_dir else "",
                            tags=tags if view is None else {**tags, "view": view.name})
    try:
        with ResultWriter(engine, view_layer, view.name if view is not None else "") as writer:
            if exported.is_empty:
                writer.push_black()
                report('WARNING', "AMCMCPPM: nothing to render (no geometry, no lights and a black "
                                  "world); the image is black")
                return
            progress = Progress(engine, settings, writer, outputs, of, label)
            engine.update_stats("", f"{label}Building acceleration structure "
                                    f"({exported.scene.triangle_count:,} triangles) and starting workers")
            result = core_render(exported.scene, settings, on_iteration=progress.on_iteration,
                                 should_stop=engine.test_break)
            writer.push(result.image)
            aov_types = {aov.name: aov.type for aov in shader_aovs(depsgraph.view_layer)}
            writer.write_data(pass_images(result.data, exported.scene.camera, aov_types))
            writer.add_metadata(crypto_metadata(view_layer, exported.cryptomatte_manifests))
            outputs.finish(result, settings.time_limit or 0.0)
            effects = ", ".join(result.effects) or "none (diffuse surfaces and lights only)"
            report('INFO', f"AMCMCPPM: optional effects this scene calls for: {effects}")
            source = result.direct_light.replace("sampled", "light samples")
            report('INFO', f"AMCMCPPM: direct light from {source}")
            for msg in result.warnings:
                report('WARNING', f"AMCMCPPM: {msg}")
            for msg in writer.problems:
                report('WARNING', f"AMCMCPPM: {label}{msg}")
            pending = outputs.pending
            if pending:
                report('INFO', f"AMCMCPPM: {label}the render ended at {result.elapsed_s:.1f} s, before "
                               f"snapshot times {', '.join(f'{t:g}' for t in pending)} s")
            done = "cancelled after" if result.interrupted else "finished in"
            engine.update_stats("", f"{label}{done} {result.passes} passes, {result.elapsed_s:.1f} s")
            engine.update_progress((of[0] + 1) / of[1])
    finally:
        outputs.close()


class Progress:
    """The core's ``on_iteration``: statistics, progress, files and progressive pushes."""

    def __init__(self, engine, settings, writer, outputs, of=(0, 1), label=""):
        self.engine = engine
        self.settings = settings
        self.writer = writer
        self.outputs = outputs
        self.schedule = PushSchedule(interval=1.0)
        self.paths_total = 0
        self.of = of                    # (this view's index, the number of views)
        self.label = label

    def on_iteration(self, result):
        stats = result.stats[-1]
        self.paths_total += int(stats.get("paths_traced", 0))
        self.engine.update_stats("", self.label + stats_line(self.settings, stats, self.paths_total))
        done = progress_fraction(self.settings, stats["pass"], stats["elapsed_s"])
        self.engine.update_progress((self.of[0] + done) / self.of[1])
        self.outputs.on_pass(result)
        if self.schedule.due():
            self.writer.push(result.image)
