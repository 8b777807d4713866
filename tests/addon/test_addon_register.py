"""Registration, defaults, panels and the extension manifest (real bpy module)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

import blender_scenes as bs
from conftest import ROOT, load_package

sys.path.insert(0, str(ROOT / "tools"))
import build_extension  # noqa: E402

ENGINE = "AMCMCPPM"


def same(a, b):
    return a == b if isinstance(b, str) else a == pytest.approx(b, rel=1e-6)


def engine_available():
    scene = bpy.context.scene
    old = scene.render.engine
    try:
        scene.render.engine = ENGINE
    except TypeError:
        return False
    scene.render.engine = old
    return True


def test_register_unregister_repeatedly(addon):
    """Unregister/register cycles leave no engine, property or panel behind and restore them."""
    from amcmcppm.amcmcppm_addon import ui
    assert engine_available()
    for _ in range(3):
        addon.unregister()
        assert not engine_available()
        assert not hasattr(bpy.types.Scene, "amcmcppm")
        assert not any(ENGINE in p.COMPAT_ENGINES for p in ui.get_panels())
        assert not hasattr(bpy.types, "AMCMCPPM_RENDER_PT_sampling")
        addon.register()
        assert engine_available()
        assert hasattr(bpy.types.Scene, "amcmcppm")
        assert hasattr(bpy.types, "AMCMCPPM_RENDER_PT_sampling")


def test_root_package_imports_without_registering():
    """pytest and Blender import the root package; bpy is needed only by register()."""
    src = (Path(__file__).resolve().parents[2] / "__init__.py").read_text()
    top_level = [line for line in src.splitlines() if line.startswith(("import ", "from "))]
    assert top_level == []
    assert callable(load_package().register)


def test_engine_flags(addon):
    from amcmcppm.amcmcppm_addon.engine import AMCMCPPMRenderEngine as E
    assert (E.bl_idname, E.bl_label) == (ENGINE, "AMCMCPPM")
    assert E.bl_use_shading_nodes_custom is False


def test_defaults_follow_core(scene):
    """Every core setting has a property of the same name whose default is the core's default,
    but those Blender's own data gives (``properties.FROM_BLENDER``: the view layer's passes)."""
    from amcmcppm.amcmcppm_addon.export import render_settings_from
    from amcmcppm.amcmcppm_addon.properties import FROM_BLENDER
    from amcmcppm.core.settings import RenderSettings
    core = RenderSettings()
    props = scene.amcmcppm
    assert set(FROM_BLENDER) <= set(RenderSettings.__dataclass_fields__)
    for name in RenderSettings.__dataclass_fields__:
        if name in FROM_BLENDER:
            assert not hasattr(props, name)
            continue
        assert hasattr(props, name), f"no property for core setting {name}"
        prop = props.bl_rna.properties[name]
        assert same(prop.default, getattr(core, name)), name
        assert prop.description, f"{name} has no description"
    assert props.bl_rna.properties["target_acceptance"].default == pytest.approx(0.60)
    fresh = bpy.data.scenes.new("Fresh").amcmcppm
    fresh.light_paths_from_cycles = False           # (by default the bounce limits are Cycles', below)
    settings = render_settings_from(fresh)
    for name in RenderSettings.__dataclass_fields__:
        assert same(getattr(settings, name), getattr(core, name)), name


def test_bounce_limits_are_cycles_light_paths_by_default(scene):
    """A new scene renders with Cycles' Light Paths (Total 12, Diffuse 4, Glossy 4, Transmission 12,
    Volume 0, both Caustics on, Transparent 8 by default), as they change; more than the engine
    traces is taken as its most, with a note (Transparent goes up to 1024 in both: no note);
    switching to the engine's own limits starts from Cycles' values; without the option the
    engine's own apply."""
    from amcmcppm.amcmcppm_addon.export import render_settings_from
    from amcmcppm.amcmcppm_addon.properties import LIGHT_PATHS
    from amcmcppm.core.settings import MAX_BOUNCES, MAX_TRANSPARENT_BOUNCES
    fresh = bpy.data.scenes.new("Fresh")
    props = fresh.amcmcppm
    assert props.light_paths_from_cycles
    limits = lambda s: tuple(getattr(s, name) for name in LIGHT_PATHS)        # noqa: E731
    assert limits(render_settings_from(props)) == (12, 4, 4, 12, 0, True, True, 8) == limits(fresh.cycles)
    fresh.cycles.max_bounces, fresh.cycles.volume_bounces = 128, 3
    fresh.cycles.caustics_refractive = False
    fresh.cycles.transparent_max_bounces = MAX_TRANSPARENT_BOUNCES
    most = (MAX_BOUNCES, 4, 4, 12, 3, True, False, MAX_TRANSPARENT_BOUNCES)
    assert limits(render_settings_from(props)) == most
    notes = props.light_path_limits()[1]
    assert len(notes) == 1 and "128" in notes[0] and str(MAX_BOUNCES) in notes[0]
    fresh.cycles.transparent_max_bounces = 100          # (more than MAX_BOUNCES: kept)
    assert render_settings_from(props).transparent_max_bounces == 100
    assert len(props.light_path_limits()[1]) == 1
    props.own_light_paths()
    assert not props.light_paths_from_cycles
    assert limits(props) == (MAX_BOUNCES, 4, 4, 12, 3, True, False, 100)
    props.diffuse_bounces = 2
    props.caustics_reflective = False
    props.transparent_max_bounces = 3
    assert limits(render_settings_from(props)) == (MAX_BOUNCES, 2, 4, 12, 3, False, False, 3)
    assert render_settings_from(props).bounce_limits.transparent == 3
    assert props.light_path_limits()[1] == []


def test_enums_have_indices_and_limits(scene):
    from amcmcppm.amcmcppm_addon import properties as p
    from amcmcppm.core import settings as core
    props = scene.amcmcppm.bl_rna.properties
    for name, values, known in (("method", core.METHODS, p.METHOD_ITEMS),
                                ("mutation", core.MUTATIONS, p.MUTATION_ITEMS),
                                ("normalisation", core.NORMALISATIONS, p.NORMALISATION_ITEMS)):
        items = props[name].enum_items
        assert [item.identifier for item in items] == list(values)
        assert set(values) <= set(known), f"core {name} values the add-on does not describe"
        assert [item.value for item in items] == [known[v][2] for v in values]
        assert all(item.description for item in items)
    assert props["target_acceptance"].hard_min > 0 and props["target_acceptance"].hard_max < 1
    assert props["alpha"].hard_min > 0 and props["alpha"].hard_max < 1
    assert props["workers"].hard_min == 0
    assert props["max_bounces"].hard_min == 0          # (0: direct light, as Cycles)
    # Cycles' range of Transparent bounces, whose most (the engine's default) counts no crossing.
    ours, cycles = (s.bl_rna.properties["transparent_max_bounces"] for s in (scene.amcmcppm, scene.cycles))
    assert (ours.hard_min, ours.hard_max) == (0, core.MAX_TRANSPARENT_BOUNCES)
    assert (cycles.hard_min, cycles.hard_max) == (0, core.MAX_TRANSPARENT_BOUNCES)
    assert ours.default == core.MAX_TRANSPARENT_BOUNCES


def test_settings_reach_core(scene):
    from amcmcppm.amcmcppm_addon.export import render_settings_from
    p = scene.amcmcppm
    p.method, p.mutation, p.target_acceptance, p.passes, p.seed = "ppm", "exact", 0.3, 7, 11
    s = render_settings_from(p)
    assert (s.method, s.mutation, s.passes, s.seed) == ("ppm", "exact", 7, 11)
    assert s.target_acceptance == pytest.approx(0.3)


def test_panels_poll_and_props_exist(scene):
    from amcmcppm.amcmcppm_addon import ui
    names = set(scene.amcmcppm.bl_rna.properties.keys())
    drawn = set()
    for panel in ui.classes:
        assert panel.__name__.startswith("AMCMCPPM_RENDER_PT_")
        assert panel.poll(bpy.context)
        for prop in panel.props:
            assert prop in names, f"{panel.__name__} draws unknown property {prop}"
        drawn.update(panel.props)
    # Every setting of the property group is on some panel.
    assert drawn == names - {"rna_type", "name"}
    scene.render.engine = "CYCLES"
    assert not ui.AMCMCPPM_RENDER_PT_sampling.poll(bpy.context)


def test_automatic_photon_count_label_follows_the_output_size(scene):
    from amcmcppm.amcmcppm_addon import ui
    from amcmcppm.core.settings import AUTO_PHOTONS_MIN, AUTO_PHOTONS_PER_PIXEL
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage, r.use_border = 1920, 1080, 100, False
    scene.amcmcppm.photons_per_pass = 0            # automatic (the default; the fixture sets 4000)
    full = int(np.ceil(AUTO_PHOTONS_PER_PIXEL * 1920 * 1080))
    assert ui.automatic_photons_label(scene) == (f"Automatic: {full:,} photons per pass and worker "
                                                 f"(from {AUTO_PHOTONS_MIN:,})")
    r.resolution_percentage = 10                    # 192 x 108 pixels: the minimum, in every pass
    assert AUTO_PHOTONS_PER_PIXEL * 192 * 108 < AUTO_PHOTONS_MIN
    assert ui.automatic_photons_label(scene) == f"Automatic: {AUTO_PHOTONS_MIN:,} photons per pass and worker"
    r.resolution_percentage = 100
    r.use_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.0, 0.5, 0.0, 1.0
    half = int(np.ceil(AUTO_PHOTONS_PER_PIXEL * 960 * 1080))
    assert f"{half:,}" in ui.automatic_photons_label(scene)
    scene.amcmcppm.first_pass_photons = 20_000     # (the first pass's count, when set)
    assert ui.automatic_photons_label(scene).endswith("(from 20,000)")
    scene.amcmcppm.photons_per_pass = 5000
    assert ui.automatic_photons_label(scene) is None


def test_panorama_panel_shows_a_panoramic_cameras_settings(scene):
    """Blender's Lens panel draws a panoramic camera's type and settings for Cycles only: our own
    subpanel does for our engine, for every type the core renders."""
    from amcmcppm.amcmcppm_addon import ui
    panel = ui.AMCMCPPM_CAMERA_PT_panorama
    assert getattr(bpy.types, panel.__name__) is panel
    cam = bs.camera()
    with bpy.context.temp_override(camera=cam.data):
        assert not panel.poll(bpy.context)
        cam.data.type = "PANO"
        assert panel.poll(bpy.context)
        scene.render.engine = "CYCLES"
        assert not panel.poll(bpy.context)
    from amcmcppm.amcmcppm_addon.export.camera import PANORAMA_TYPES
    assert set(panel.props) == set(PANORAMA_TYPES)
    known = set(bpy.types.Camera.bl_rna.properties.keys())
    assert all(name in known for names in panel.props.values() for name in names)


def test_ray_visibility_panel_shows_the_rays_the_engine_follows(scene):
    """Blender's Visibility panel draws an object's ray visibility for Cycles and EEVEE only (and
    the Holdout mask for every engine): our subpanel draws the boxes the exporter reads."""
    from amcmcppm.amcmcppm_addon import ui
    panel = ui.AMCMCPPM_OBJECT_PT_ray_visibility
    assert getattr(bpy.types, panel.__name__) is panel
    assert ENGINE in bpy.types.OBJECT_PT_visibility.COMPAT_ENGINES
    card = bs.plane("Card")
    cam = bs.camera()
    with bpy.context.temp_override(object=card):
        assert panel.poll(bpy.context)
        scene.render.engine = "CYCLES"
        assert not panel.poll(bpy.context)
        scene.render.engine = ENGINE
    with bpy.context.temp_override(object=bs.hair_curves("Fur", [[(0, 0, 0), (0, 0, 1)]])):
        assert panel.poll(bpy.context)                   # (hair renders since stop 56)
    with bpy.context.temp_override(object=cam):
        assert not panel.poll(bpy.context)


def test_world_ray_visibility_panel_draws_the_boxes_the_exporter_reads(scene):
    """The world's Ray Visibility (Cycles' properties, drawn by Cycles' panel for Cycles only)."""
    from amcmcppm.amcmcppm_addon import ui
    panel = ui.AMCMCPPM_WORLD_PT_ray_visibility
    assert getattr(bpy.types, panel.__name__) is panel
    world = bs.world((0.1, 0.1, 0.1))
    known = set(type(world.cycles_visibility).bl_rna.properties.keys())
    assert {name for name, _ in panel.props} <= known
    with bpy.context.temp_override(world=world):
        assert panel.poll(bpy.context)
        scene.render.engine = "CYCLES"
        assert not panel.poll(bpy.context)
        scene.render.engine = ENGINE


def test_passes_panel_draws_the_data_passes_the_engine_writes(scene):
    """View Layer > Passes (Blender's panels list EEVEE and Workbench only): our panel draws the
    boxes of the passes ``engine.DATA_PASSES`` registers (Z, Mist, Position, Normal, UV, Cycles'
    Denoising Data, Object and Material Index), its Light subpanel those of the light passes and
    Shadow Catcher, for our engine alone; those passes are Cycles' (names, channels, types, in its
    order; but Cycles' Noisy passes, its denoiser's input).  World > Mist Pass (drawn by Cycles'
    panel for Cycles only) shows when a view layer asks for Mist, World > Ambient Occlusion when one
    asks for that pass."""
    import cycles.engine
    from amcmcppm.amcmcppm_addon import ui
    from amcmcppm.amcmcppm_addon.engine import DATA_PASSES
    from amcmcppm.core.light_passes import LIGHT_PASSES
    panel = ui.AMCMCPPM_VIEWLAYER_PT_passes
    assert getattr(bpy.types, panel.__name__) is panel
    layer = scene.view_layers[0]
    for _, owner, prop, _ in DATA_PASSES:
        holder = getattr(layer, owner) if owner else layer
        assert prop in holder.bl_rna.properties.keys(), (owner, prop)
        setattr(holder, prop, True)
    in_light = LIGHT_PASSES + ("ao", "shadow_catcher")
    light = [(owner, prop) for _, owner, prop, core in DATA_PASSES if core in in_light]
    assert list(panel.data + panel.indexes) == [prop for _, owner, prop, core in DATA_PASSES
                                                if not owner and core not in in_light]
    # (View Layer > Passes > Light draws the light passes' boxes and Shadow Catcher, Cycles' Light
    # panel's)
    rows = ui.AMCMCPPM_VIEWLAYER_PT_light.rows
    assert [(owner, prop) for _, owner, props in rows for prop, _ in props] == light and len(light) == 15
    assert getattr(bpy.types, "AMCMCPPM_VIEWLAYER_PT_light").bl_parent_id == panel.__name__
    ours = [(name, chan_id, kind) for (name, _, chan_id, kind), *_ in DATA_PASSES]
    assert all(channels == len(chan_id) for (_, channels, chan_id, _), *_ in DATA_PASSES)
    theirs = [p for p in cycles.engine.list_render_passes(scene, layer)
              if p[0] != "Combined" and not p[0].startswith("Noisy ")]
    order = [p[0] for p in theirs]
    assert sorted(ours, key=lambda p: order.index(p[0])) == theirs
    with bpy.context.temp_override(view_layer=scene.view_layers[0]):
        assert panel.poll(bpy.context)
        scene.render.engine = "CYCLES"
        assert not panel.poll(bpy.context)
        scene.render.engine = ENGINE
    world = bs.world((0.1, 0.1, 0.1))
    # (World > Ambient Occlusion's Distance likewise when a view layer asks for that pass)
    for panel, settings, box in ((ui.AMCMCPPM_WORLD_PT_mist, world.mist_settings, "use_pass_mist"),
                                 (ui.AMCMCPPM_WORLD_PT_ambient_occlusion, world.light_settings,
                                  "use_pass_ambient_occlusion")):
        assert getattr(bpy.types, panel.__name__) is panel and panel.box == box
        assert set(panel.props) <= set(type(settings).bl_rna.properties.keys())
        with bpy.context.temp_override(world=world):
            assert panel.poll(bpy.context)
            setattr(layer, box, False)
            assert not panel.poll(bpy.context)
            setattr(layer, box, True)
            scene.render.engine = "CYCLES"
            assert not panel.poll(bpy.context)
            scene.render.engine = ENGINE


def drawn_boxes(draw):
    """The properties (``"Struct.property"``) ``draw(popup)`` draws, in their order, and the index
    of the column of each: drawn into a real layout, a popup menu's, begun and never shown (showing
    it needs a window that draws, which bpy as a module has not; the popup's few kilobytes are left
    unfreed, which Blender names at exit), and read back by ``UILayout.introspect``."""
    popup = bpy.context.window_manager.popmenu_begin__internal("test", icon='NONE')
    draw(popup)
    out = []

    def walk(item, column):
        if "rna" in item:
            out.append((item["rna"].split("[")[0], column))
        for i, child in enumerate(item.get("items", ())):
            walk(child, i if column is None else column)

    for root in popup.layout.introspect():
        walk(root, None)
    return out


def test_an_area_lights_portal_box_shows_for_the_engine(scene):
    """Light > Portal (Cycles' ``is_portal``, which Cycles' light panel draws for Cycles only):
    appended to EEVEE's light panel, shown for our engine, it draws the box once for an area light,
    not for a point light nor for another engine (the export: ``test_addon_export.py``)."""
    from amcmcppm.amcmcppm_addon import ui
    panel = bpy.types.DATA_PT_EEVEE_light
    assert ENGINE in panel.COMPAT_ENGINES and ui.draw_light_portal in panel.draw._draw_funcs
    area, point = bs.light("AREA"), bs.light("POINT")
    for ob, shown in ((area, True), (point, False)):
        with bpy.context.temp_override(light=ob.data):
            boxes = [name for name, _ in drawn_boxes(lambda popup: ui.draw_light_portal(popup, bpy.context))]
            assert boxes == ["CyclesLightSettings.is_portal"] * shown, (ob.name, boxes)
    scene.render.engine = "CYCLES"
    with bpy.context.temp_override(light=area.data):
        assert not drawn_boxes(lambda popup: ui.draw_light_portal(popup, bpy.context))
    scene.render.engine = ENGINE


def test_shadow_catcher_boxes_show_for_the_engine(scene):
    """Object > Visibility > Mask > Shadow Catcher, which Cycles' Visibility panel draws for Cycles
    only, and Blender's (shown for our engine) does not, drawing Holdout alone: ours, appended to
    Blender's panel, draws it once, right below Holdout, for the objects whose box the exporter
    reads (meshes, text, hair, empties instancing a collection), not for lights, cameras or other empties,
    nor for another engine.  View Layer > Passes > Light draws Cycles' Shadow Catcher pass box in
    the column of Emission, Environment and Ambient Occlusion ("Other"), as Cycles' Light panel.
    (The pass and the export: ``test_addon_engine.py``, ``test_addon_export.py``.)"""
    import cycles.ui
    from amcmcppm.amcmcppm_addon import ui
    visibility = bpy.types.OBJECT_PT_visibility
    assert ENGINE in visibility.COMPAT_ENGINES
    assert ENGINE not in cycles.ui.CYCLES_OBJECT_PT_visibility.COMPAT_ENGINES
    assert ui.draw_shadow_catcher in visibility.draw._draw_funcs
    card, lamp, cam = bs.plane("Card"), bs.light("POINT"), bs.camera()
    fur = bs.hair_curves("Fur", [[(0, 0, 0), (0, 0, 1)]])
    text = bpy.data.objects.new("Text", bpy.data.curves.new("Text", "FONT"))
    instancer, bare = bpy.data.objects.new("Instancer", None), bpy.data.objects.new("Empty", None)
    instancer.instance_type, instancer.instance_collection = "COLLECTION", bpy.data.collections.new("Src")
    for ob in (text, instancer, bare):
        scene.collection.objects.link(ob)
    holdout, catcher = "Object.is_holdout", "Object.is_shadow_catcher"
    for ob, shown in ((card, True), (text, True), (fur, True), (instancer, True), (lamp, False),
                      (cam, False), (bare, False)):
        with bpy.context.temp_override(object=ob):
            assert visibility.poll(bpy.context)
            boxes = [name for name, _ in drawn_boxes(lambda popup: visibility.draw(popup, bpy.context))]
            assert boxes.count(holdout) == 1 and boxes.count(catcher) == shown, (ob.name, boxes)
            assert boxes[-1 - shown:] == [holdout, catcher][:1 + shown], (ob.name, boxes)
    scene.render.engine = "CYCLES"
    with bpy.context.temp_override(object=card):
        assert not drawn_boxes(lambda popup: ui.draw_shadow_catcher(popup, bpy.context))
    scene.render.engine = ENGINE
    layer = scene.view_layers[0]
    panel = ui.AMCMCPPM_VIEWLAYER_PT_light
    with bpy.context.temp_override(view_layer=layer):
        assert panel.poll(bpy.context)
    boxes = dict(drawn_boxes(lambda popup: ui.draw_pass_boxes(popup.layout, layer, panel.rows)))
    other = {boxes[f"ViewLayer.use_pass_{name}"] for name in ("emit", "environment", "ambient_occlusion")}
    assert other == {boxes["CyclesRenderLayerSettings.use_pass_shadow_catcher"]}
    assert boxes["CyclesRenderLayerSettings.use_pass_volume_direct"] not in other


def test_cryptomatte_and_aov_panels_show_for_the_engine(scene):
    """View Layer > Passes > Cryptomatte and Shader AOV for our engine (Blender's panel bodies):
    the passes the Cryptomatte boxes ask for are Cycles' (names, channels r, g, b, a, two levels a
    pass: Levels 5 makes 3)."""
    import cycles.engine
    from amcmcppm.amcmcppm_addon import ui
    from amcmcppm.amcmcppm_addon.engine import CRYPTO_PASSES, crypto_pass_count
    panel = ui.AMCMCPPM_VIEWLAYER_PT_cryptomatte
    assert getattr(bpy.types, panel.__name__) is panel
    layer = scene.view_layers[0]
    assert list(panel.props) == [prop for _, prop, _ in CRYPTO_PASSES]
    for prop in panel.props:
        setattr(layer, prop, True)
    layer.pass_cryptomatte_depth = 5
    ours = [(f"{prefix}{i:02d}", "rgba", 'COLOR') for prefix, _, _ in CRYPTO_PASSES
            for i in range(crypto_pass_count(layer))]
    theirs = [p for p in cycles.engine.list_render_passes(scene, layer) if p[0].startswith("Crypto")]
    assert ours == theirs and len(ours) == 9
    aov = ui.AMCMCPPM_VIEWLAYER_PT_aov            # (the Shader AOV list, Blender's panel body)
    assert getattr(bpy.types, aov.__name__) is aov
    assert aov.bl_parent_id == panel.bl_parent_id == ui.AMCMCPPM_VIEWLAYER_PT_passes.__name__
    with bpy.context.temp_override(view_layer=layer):
        assert panel.poll(bpy.context) and aov.poll(bpy.context)
        scene.render.engine = "CYCLES"
        assert not panel.poll(bpy.context) and not aov.poll(bpy.context)
        scene.render.engine = ENGINE


def test_light_group_panels_show_for_the_engine(scene):
    """View Layer > Passes > Light Groups (Blender's list, whose own panel shows for Cycles only),
    Object > Shading > Light Group and World > Light Group (Cycles' fields, drawn for Cycles only)
    show for our engine alone; Blender's and Cycles' panels do not (no panel twice).  (The passes
    they make: ``test_addon_engine.py``'s light group tests.)"""
    import cycles.ui
    from amcmcppm.amcmcppm_addon import ui
    layer = scene.view_layers[0]
    panel = ui.AMCMCPPM_VIEWLAYER_PT_lightgroups
    assert getattr(bpy.types, panel.__name__) is panel
    assert panel.bl_parent_id == ui.AMCMCPPM_VIEWLAYER_PT_passes.__name__
    assert panel.bl_label == "Light Groups"
    for theirs in (bpy.types.VIEWLAYER_PT_layer_passes_lightgroups,
                   cycles.ui.CYCLES_RENDER_PT_passes_lightgroups, cycles.ui.CYCLES_OBJECT_PT_lightgroup,
                   cycles.ui.CYCLES_WORLD_PT_settings_light_group):
        assert ENGINE not in theirs.COMPAT_ENGINES, theirs.__name__
    obj_panel, world_panel = ui.AMCMCPPM_OBJECT_PT_lightgroup, ui.AMCMCPPM_WORLD_PT_light_group
    assert obj_panel.bl_parent_id == "OBJECT_PT_shading"
    assert ENGINE in bpy.types.OBJECT_PT_shading.COMPAT_ENGINES
    for p in (obj_panel, world_panel):
        assert getattr(bpy.types, p.__name__) is p
    card, lamp, world = bs.plane("Card"), bs.light("POINT"), bs.world((0.1, 0.1, 0.1))
    for ob in (card, lamp):
        with bpy.context.temp_override(object=ob, view_layer=layer, world=world):
            assert bpy.types.OBJECT_PT_shading.poll(bpy.context)
            assert all(p.poll(bpy.context) for p in (panel, obj_panel, world_panel))
            scene.render.engine = "CYCLES"
            assert not any(p.poll(bpy.context) for p in (panel, obj_panel, world_panel))
            scene.render.engine = ENGINE


def test_light_linking_panels_show_for_engine(scene):
    """Object > Shading > Light Linking and Shadow Linking (Blender's panels, whose parent lists
    the engines that show them) show for lights and meshes: the exporter reads both."""
    assert ENGINE in bpy.types.OBJECT_PT_shading.COMPAT_ENGINES
    for name in ("OBJECT_PT_light_linking", "OBJECT_PT_shadow_linking"):
        assert getattr(bpy.types, name).bl_parent_id == "OBJECT_PT_shading"
    for ob in (bs.plane("Card"), bs.light("POINT")):
        with bpy.context.temp_override(object=ob):
            assert bpy.types.OBJECT_PT_shading.poll(bpy.context)


def test_builtin_panels_show_for_engine(addon):
    """Format, output, colour management, camera, light, material and world panels include us
    (the material's and the world's Volume too)."""
    wanted = {"RENDER_PT_format", "RENDER_PT_output", "RENDER_PT_color_management", "DATA_PT_camera",
              "DATA_PT_camera_dof", "DATA_PT_EEVEE_light", "DATA_PT_spot",
              "EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface", "EEVEE_MATERIAL_PT_volume",
              "EEVEE_WORLD_PT_surface", "EEVEE_WORLD_PT_volume"}
    panels = {p.__name__: p for p in bpy.types.Panel.__subclasses__()}
    for name in wanted:
        assert ENGINE in panels[name].COMPAT_ENGINES, name
    for name in ("DATA_PT_light", "RENDER_PT_simplify"):
        assert ENGINE not in panels[name].COMPAT_ENGINES, name


def test_manifest_validates(repo_root):
    """Blender's own extension validator accepts the repository root."""
    cli = build_extension.blender_ext_cli()
    out = subprocess.run([sys.executable, str(cli), "validate", str(repo_root)], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
