"""Render Properties panels for ``scene.amcmcppm``, and Blender's own panels for our engine.

Panels follow Cycles' pattern: a :class:`AMCMCPPMButtonsPanel` mixin with
``COMPAT_ENGINES`` and ``poll``, panel classes named ``AMCMCPPM_RENDER_PT_*``.
Each panel lists the properties it draws in ``props`` (tests check that they
exist).  :func:`get_panels` selects Blender's built-in panels (format, output,
colour management, camera, light, material, world) that should also show for
this engine; ``register`` adds our engine to their ``COMPAT_ENGINES``, and ``appended`` draw
functions to some of them (Object > Visibility's Shadow Catcher box, Light > Portal).
"""
import bpy
from bl_ui.properties_view_layer import (ViewLayerAOVPanelHelper, ViewLayerCryptomattePanelHelper,
                                         ViewLayerLightgroupsPanelHelper)

from ..core.settings import AUTO_PHOTONS_MIN, RenderSettings
from .engine import AMCMCPPMRenderEngine
from .export.camera import rendered_pixels

ENGINE_ID = AMCMCPPMRenderEngine.bl_idname


class AMCMCPPMButtonsPanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE_ID}
    props = ()

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.amcmcppm
        col = layout.column()
        col.active = self.is_active(settings)
        for name in self.props:
            row = col.row()
            row.active = self.prop_active(settings, name)
            row.prop(settings, name)

    @staticmethod
    def prop_active(settings, name):
        """Whether property ``name`` has an effect with the other ``settings``."""
        return True

    @staticmethod
    def is_active(settings):
        return True


class AMCMCPPM_RENDER_PT_sampling(AMCMCPPMButtonsPanel, bpy.types.Panel):
    bl_label = "Sampling"
    props = ("method", "passes", "time_limit", "photons_per_pass", "seed", "pixel_jitter", "focus_photons")

    def draw(self, context):
        super().draw(context)
        text = automatic_photons_label(context.scene)
        if text:
            self.layout.label(text=text, icon='INFO')


def automatic_photons_label(scene):
    """What "Photons per Pass" = 0 (automatic) means at the scene's output size, or None."""
    props = scene.amcmcppm
    if props.photons_per_pass:
        return None
    n = RenderSettings().photons_for(rendered_pixels(scene.render))
    start = props.first_pass_photons or AUTO_PHOTONS_MIN
    return f"Automatic: {n:,} photons per pass and worker" + (f" (from {start:,})" if n > start else "")


class AMCMCPPM_RENDER_PT_viewport(AMCMCPPMButtonsPanel, bpy.types.Panel):
    bl_label = "Viewport"
    bl_parent_id = "AMCMCPPM_RENDER_PT_sampling"
    bl_options = {'DEFAULT_CLOSED'}
    props = ("viewport_passes", "viewport_pixel_size")


class AMCMCPPM_RENDER_PT_markov_chains(AMCMCPPMButtonsPanel, bpy.types.Panel):
    bl_label = "Markov Chains"
    bl_parent_id = "AMCMCPPM_RENDER_PT_sampling"
    props = ("target_acceptance", "mutation", "chains", "normalisation", "initial_mutation_size")

    @staticmethod
    def is_active(settings):
        return settings.method != "ppm"


class AMCMCPPM_RENDER_PT_photons(AMCMCPPMButtonsPanel, bpy.types.Panel):
    bl_label = "Photon Gathering"
    props = ("direct_light", "direct_samples", "initial_radius_px", "alpha", "bias_correction",
             "edge_coverage", "glossy_through_roughness")

    @staticmethod
    def prop_active(settings, name):
        return name != "direct_samples" or settings.direct_light == "sampled"


class AMCMCPPM_RENDER_PT_light_paths(AMCMCPPMButtonsPanel, bpy.types.Panel):
    """Bounce limits (the transparent one too) and caustics toggles as Cycles' Light Paths > Max Bounces
    and Caustics: Cycles' own settings of the scene (the same names), or with Use Cycles' Light Paths
    off the engine's."""
    bl_label = "Light Paths"
    props = ("light_paths_from_cycles", "max_bounces", "diffuse_bounces", "glossy_bounces",
             "transmission_bounces", "volume_bounces", "transparent_max_bounces", "caustics_reflective",
             "caustics_refractive")
    labels = {"max_bounces": "Total", "diffuse_bounces": "Diffuse", "glossy_bounces": "Glossy",
              "transmission_bounces": "Transmission", "volume_bounces": "Volume",
              "transparent_max_bounces": "Transparent", "caustics_reflective": "Reflective",
              "caustics_refractive": "Refractive"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.amcmcppm
        layout.prop(settings, "light_paths_from_cycles")
        cycles = getattr(context.scene, "cycles", None)
        source = cycles if settings.light_paths_from_cycles and cycles is not None else settings
        # As Cycles' Max Bounces: the bounce limits, then Transparent in a column of its own.
        bounces = layout.column(align=True)
        transparent = layout.column(align=True)
        caustics = layout.column(heading="Caustics", align=True)
        for name in self.props[1:]:
            col = (caustics if name.startswith("caustics_") else
                   transparent if name == "transparent_max_bounces" else bounces)
            col.prop(source, name, text=self.labels[name])


class AMCMCPPM_RENDER_PT_performance(AMCMCPPMButtonsPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {'DEFAULT_CLOSED'}
    props = ("workers", "first_pass_photons")


class AMCMCPPM_RENDER_PT_statistics_output(AMCMCPPMButtonsPanel, bpy.types.Panel):
    bl_label = "Statistics Output"
    bl_options = {'DEFAULT_CLOSED'}
    props = ("stats_path", "snapshot_times", "snapshot_dir")

    def draw(self, context):
        super().draw(context)
        self.layout.operator("amcmcppm.export_scene", icon='EXPORT')


class AMCMCPPM_RENDER_PT_film(AMCMCPPMButtonsPanel, bpy.types.Panel):
    """Film: a transparent background (Blender's own setting, which Cycles' Film panel shows)."""
    bl_label = "Film"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.render, "film_transparent", text="Transparent")


class AMCMCPPM_RENDER_PT_film_pixel_filter(AMCMCPPMButtonsPanel, bpy.types.Panel):
    """Cycles' Pixel Filter settings of the scene (``scene.cycles``), which the engine uses too."""
    bl_label = "Pixel Filter"
    bl_parent_id = "AMCMCPPM_RENDER_PT_film"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        cycles = getattr(context.scene, "cycles", None)
        if cycles is None:
            layout.label(text="Blackman-Harris, 1.5 px (the Cycles add-on is off)", icon='INFO')
            return
        col = layout.column()
        col.prop(cycles, "pixel_filter_type", text="Type")
        if cycles.pixel_filter_type != 'BOX':
            col.prop(cycles, "filter_width", text="Width")


class AMCMCPPM_CAMERA_PT_panorama(bpy.types.Panel):
    """A panoramic camera's settings under Blender's Lens panel, which draws them for Cycles only."""
    bl_label = "Panorama"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "data"
    bl_parent_id = "DATA_PT_lens"
    COMPAT_ENGINES = {ENGINE_ID}
    # The camera properties drawn for each panorama type (the others render as equirectangular).
    props = {"EQUIRECTANGULAR": ("latitude_min", "latitude_max", "longitude_min", "longitude_max"),
             "FISHEYE_EQUIDISTANT": ("fisheye_fov",),
             "FISHEYE_EQUISOLID": ("fisheye_lens", "fisheye_fov"),
             "MIRRORBALL": ()}

    @classmethod
    def poll(cls, context):
        cam = context.camera
        return context.engine in cls.COMPAT_ENGINES and cam is not None and cam.type == 'PANO'

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        cam = context.camera
        col = layout.column()
        col.prop(cam, "panorama_type")
        names = self.props.get(cam.panorama_type)
        if names is None:
            col.label(text="Not supported: renders as Equirectangular", icon='ERROR')
        for name in names or ():
            col.prop(cam, name)


class AMCMCPPM_OBJECT_PT_ray_visibility(bpy.types.Panel):
    """The object's ray visibility under Blender's Visibility panel (which draws it for Cycles and
    EEVEE only), for the rays our engine follows: camera rays, and camera paths a mirror or glass
    reflected (Glossy) or refracted (Transmission).  Diffuse and shadow rays are photons here,
    which always meet the object.  An emitter's boxes (a light's, or an emissive mesh's) also say
    which rays its light reaches, Diffuse and Volume Scatter too (``Lights.exclude``), so those two
    are drawn for lights.  A mesh's Shadow box lets the direct light through it
    (``CASTS_NO_SHADOW``).  Blender's panel draws the Holdout mask, and below it, for our engine,
    Shadow Catcher (:func:`draw_shadow_catcher`)."""
    bl_label = "Ray Visibility"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_visibility"
    COMPAT_ENGINES = {ENGINE_ID}
    OBJECT_TYPES = {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT', 'POINTCLOUD', 'CURVES', 'LIGHT'}

    @classmethod
    def poll(cls, context):
        ob = context.object
        return context.engine in cls.COMPAT_ENGINES and ob is not None and ob.type in cls.OBJECT_TYPES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        ob = context.object
        col = layout.column(heading="Rays")
        col.prop(ob, "visible_camera", text="Camera", toggle=False)
        col.prop(ob, "visible_glossy", text="Glossy", toggle=False)
        col.prop(ob, "visible_transmission", text="Transmission", toggle=False)
        if ob.type == 'LIGHT':
            col.prop(ob, "visible_diffuse", text="Diffuse", toggle=False)
            col.prop(ob, "visible_volume_scatter", text="Volume Scatter", toggle=False)
        else:
            col.prop(ob, "visible_shadow", text="Shadow", toggle=False)


# Objects whose Shadow Catcher box the exporter reads: those it renders (``export.mesh``; a curve's
# or a text's evaluated mesh, hair curves) and the empties that instance a collection (an instancer
# that is a catcher makes its instances catchers, as in Cycles).
CATCHER_TYPES = {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT', 'POINTCLOUD', 'CURVES'}


def draw_shadow_catcher(self, context):
    """Object > Visibility > Mask > Shadow Catcher for our engine, appended to Blender's Visibility
    panel (``OBJECT_PT_visibility``, which draws the Holdout box alone; Cycles' own panel draws
    Shadow Catcher for Cycles only), so that it shows right below Holdout: the object shows only
    the shadows and light the other objects cast on it (``SHADOW_CATCHER``, ``core.shadow_catcher``)."""
    ob = context.object
    if context.engine != ENGINE_ID or ob is None or not (
            ob.type in CATCHER_TYPES or (ob.instance_type == 'COLLECTION' and ob.instance_collection)):
        return
    layout = self.layout
    layout.use_property_split = True
    layout.column().prop(ob, "is_shadow_catcher")


def draw_light_portal(self, context):
    """Light > Portal for an area light (Cycles' ``cycles.is_portal``, drawn by Cycles' light panel
    for Cycles only), appended to EEVEE's light panel as shown for our engine: a portal in a window
    emits nothing, and the photons from afar (the world's, the sun's) are aimed through it
    (``World.portals``, ``core.lights.Focus.through``), as are the world's light samples with
    Direct Light "Light Samples"."""
    light = context.light
    if context.engine != ENGINE_ID or light is None or light.type != 'AREA' or not hasattr(light, "cycles"):
        return
    layout = self.layout
    layout.use_property_split = True
    layout.column().prop(light.cycles, "is_portal", text="Portal")


class AMCMCPPM_WORLD_PT_ray_visibility(bpy.types.Panel):
    """The world's Ray Visibility (Cycles' ``cycles_visibility``, drawn by Cycles' panel for Cycles
    only): Camera off shows black past the scene, the others keep the world's light from those rays
    (``World.exclude``).  Drawn only where Cycles, which registers those properties, is enabled."""
    bl_label = "Ray Visibility"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "world"
    bl_options = {'DEFAULT_CLOSED'}
    COMPAT_ENGINES = {ENGINE_ID}
    props = (("camera", "Camera"), ("diffuse", "Diffuse"), ("glossy", "Glossy"),
             ("transmission", "Transmission"), ("scatter", "Volume Scatter"))

    @classmethod
    def poll(cls, context):
        world = context.world
        return (context.engine in cls.COMPAT_ENGINES and world is not None
                and getattr(world, "cycles_visibility", None) is not None)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        visibility = context.world.cycles_visibility
        col = layout.column(heading="Rays")
        for name, text in self.props:
            col.prop(visibility, name, text=text, toggle=False)


def draw_light_group(layout, owner, view_layer):
    """An object's or a world's Light Group field as Cycles draws it: the name, searched among
    ``view_layer``'s light groups (any name may be typed; one the view layer does not list is no
    group), and a button that adds a typed name to the view layer's list."""
    row = layout.row(align=True)
    row.use_property_decorate = False
    sub = row.column(align=True)
    sub.prop_search(owner, "lightgroup", view_layer, "lightgroups", text="Light Group",
                    results_are_suggestions=True)
    sub = row.column(align=True)
    sub.enabled = bool(owner.lightgroup) and owner.lightgroup not in view_layer.lightgroups
    sub.operator("scene.view_layer_add_lightgroup", icon='ADD', text="").name = owner.lightgroup


class AMCMCPPMContextPanel:
    """A Properties panel shown for this engine alone where the context has an ``owner`` (its
    attribute: ``"object"``, ``"world"``, ``"view_layer"``)."""
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    COMPAT_ENGINES = {ENGINE_ID}
    owner = "object"

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and getattr(context, cls.owner, None) is not None


class AMCMCPPMLightGroupPanel(AMCMCPPMContextPanel):
    """A Light Group field of the ``owner`` in context (``"object"`` or ``"world"``), as Cycles
    draws it for Cycles only (:func:`draw_light_group`)."""
    bl_label = "Light Group"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        draw_light_group(layout, getattr(context, self.owner), context.view_layer)


class AMCMCPPM_OBJECT_PT_lightgroup(AMCMCPPMLightGroupPanel, bpy.types.Panel):
    """Object > Shading > Light Group (Blender's Shading panel shows for this engine): the light
    group whose pass holds the light of this light or emissive object (``Lights.group``,
    ``Scene.emitter_group``)."""
    bl_context = "object"
    bl_parent_id = "OBJECT_PT_shading"


class AMCMCPPM_WORLD_PT_light_group(AMCMCPPMLightGroupPanel, bpy.types.Panel):
    """World > Light Group (Cycles draws it under its World > Settings): the light group whose pass
    holds the world's light and its sky's sun disc (``World.group``)."""
    bl_context = "world"
    owner = "world"


class AMCMCPPMWorldPassPanel(AMCMCPPMContextPanel):
    """A World panel of a pass's settings, shown when some view layer asks for the pass (``box``)."""
    bl_context = "world"
    bl_options = {'DEFAULT_CLOSED'}
    owner = "world"
    box = ""

    @classmethod
    def poll(cls, context):
        return super().poll(context) and any(getattr(layer, cls.box) for layer in context.scene.view_layers)


class AMCMCPPM_WORLD_PT_mist(AMCMCPPMWorldPassPanel, bpy.types.Panel):
    """World > Mist Pass (Blender's mist settings, drawn by Cycles' panel for Cycles only): where the
    Mist pass starts, its depth and falloff; shown, as Cycles', when some view layer asks for Mist."""
    bl_label = "Mist Pass"
    box = "use_pass_mist"
    props = ("start", "depth", "falloff")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        mist = context.world.mist_settings
        col = layout.column(align=True)
        col.prop(mist, "start")
        col.prop(mist, "depth")
        layout.column().prop(mist, "falloff")


class AMCMCPPM_WORLD_PT_ambient_occlusion(AMCMCPPMWorldPassPanel, bpy.types.Panel):
    """World > Ambient Occlusion: the Distance the Ambient Occlusion pass's rays look for what
    occludes them (Blender's setting, which Cycles' panel draws for Cycles only; its Factor adds AO
    to the image in Cycles, which this engine does not do); shown when some view layer asks for the
    pass."""
    bl_label = "Ambient Occlusion"
    box = "use_pass_ambient_occlusion"
    props = ("distance",)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(context.world.light_settings, "distance")


class AMCMCPPMViewLayerPanel(AMCMCPPMContextPanel):
    """A panel of the View Layer Properties shown for this engine alone."""
    bl_context = "view_layer"
    owner = "view_layer"


class AMCMCPPM_VIEWLAYER_PT_passes(AMCMCPPMViewLayerPanel, bpy.types.Panel):
    """View Layer Properties > Passes: the data passes the engine writes beside Combined, as Cycles'
    Data panel (Z, Mist, Position, Normal and UV of the surfaces camera rays stop on, Cycles'
    Denoising Data box for the Denoising Normal, Albedo and Depth, and the Object and Material
    Index; ``engine.DATA_PASSES``)."""
    bl_label = "Passes"
    # The view layer's boxes, in Cycles' order (its Data panel's Include and Indexes columns).
    data = ("use_pass_z", "use_pass_mist", "use_pass_position", "use_pass_normal", "use_pass_uv")
    indexes = ("use_pass_object_index", "use_pass_material_index")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layer = context.view_layer
        col = layout.column(heading="Data", align=True)
        for name in self.data:
            col.prop(layer, name)
        cycles = getattr(layer, "cycles", None)
        if cycles is not None:
            # (Cycles' Denoising Data box: the Denoising Normal, Albedo and Depth passes)
            col.prop(cycles, "denoising_store_passes", text="Denoising Data")
        col = layout.column(heading="Indexes", align=True)
        for name in self.indexes:
            col.prop(layer, name)


class AMCMCPPM_VIEWLAYER_PT_light(AMCMCPPMViewLayerPanel, bpy.types.Panel):
    """View Layer Properties > Passes > Light: Cycles' light passes (Diffuse, Glossy, Transmission
    Direct, Indirect and Color; Volume Direct and Indirect; Emission, Environment and Ambient
    Occlusion) and its Shadow Catcher pass, as its Light panel draws them (``engine.DATA_PASSES``,
    ``core.light_passes``, ``core.shadow_catcher``)."""
    bl_label = "Light"
    bl_parent_id = "AMCMCPPM_VIEWLAYER_PT_passes"
    # (heading, the view layer's box or its Cycles settings' ("cycles"), ((property, label), ...));
    # a row without a heading (None) goes on with the column above.
    rows = tuple((kind.capitalize(), "", tuple((f"use_pass_{kind}_{part}", part.capitalize())
                                               for part in ("direct", "indirect", "color")))
                 for kind in ("diffuse", "glossy", "transmission")) + (
        ("Volume", "cycles", (("use_pass_volume_direct", "Direct"),
                              ("use_pass_volume_indirect", "Indirect"))),
        ("Other", "", (("use_pass_emit", "Emission"), ("use_pass_environment", "Environment"),
                       ("use_pass_ambient_occlusion", "Ambient Occlusion"))),
        (None, "cycles", (("use_pass_shadow_catcher", "Shadow Catcher"),)))

    def draw(self, context):
        draw_pass_boxes(self.layout, context.view_layer, self.rows)


def draw_pass_boxes(layout, layer, rows):
    """The boxes of view layer ``layer`` (or of its ``owner`` settings) in columns, as ``rows`` of
    :class:`AMCMCPPM_VIEWLAYER_PT_light` give them: (heading, owner, ((property, label), ...)), a
    heading of None going on with the column above; an owner the view layer lacks (Cycles off)
    is left out."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    col = layout
    for heading, owner, props in rows:
        holder = getattr(layer, owner, None) if owner else layer
        if holder is None:
            continue
        if heading is not None:
            col = layout.column(heading=heading, align=True)
        for prop, text in props:
            col.prop(holder, prop, text=text)


class AMCMCPPM_VIEWLAYER_PT_cryptomatte(ViewLayerCryptomattePanelHelper, bpy.types.Panel):
    """View Layer Properties > Passes > Cryptomatte: Object, Material, Asset and Levels (Blender's
    own panel body, as Cycles shows it; ``engine.CRYPTO_PASSES``, ``core.cryptomatte``)."""
    bl_parent_id = "AMCMCPPM_VIEWLAYER_PT_passes"
    COMPAT_ENGINES = {ENGINE_ID}
    props = ("use_pass_cryptomatte_object", "use_pass_cryptomatte_material", "use_pass_cryptomatte_asset")


class AMCMCPPM_VIEWLAYER_PT_aov(ViewLayerAOVPanelHelper, bpy.types.Panel):
    """View Layer Properties > Passes > Shader AOV: the view layer's AOV list (Blender's own panel
    body, as Cycles shows it), whose passes the materials' AOV Output nodes write."""
    bl_parent_id = "AMCMCPPM_VIEWLAYER_PT_passes"
    COMPAT_ENGINES = {ENGINE_ID}


class AMCMCPPM_VIEWLAYER_PT_lightgroups(ViewLayerLightgroupsPanelHelper, bpy.types.Panel):
    """View Layer Properties > Passes > Light Groups: the view layer's light groups (Blender's own
    panel body, as Cycles shows it), each of which has a ``Combined_<name>`` pass of the light its
    lights, emissive objects or world send (``engine.LIGHTGROUP_PASS``)."""
    bl_parent_id = "AMCMCPPM_VIEWLAYER_PT_passes"
    COMPAT_ENGINES = {ENGINE_ID}


classes = (
    AMCMCPPM_RENDER_PT_sampling,
    AMCMCPPM_RENDER_PT_viewport,
    AMCMCPPM_RENDER_PT_markov_chains,
    AMCMCPPM_RENDER_PT_photons,
    AMCMCPPM_RENDER_PT_light_paths,
    AMCMCPPM_RENDER_PT_performance,
    AMCMCPPM_RENDER_PT_statistics_output,
    AMCMCPPM_RENDER_PT_film,
    AMCMCPPM_RENDER_PT_film_pixel_filter,
)

# Built-in panels for Blender's own renderer that do not fit this engine.
EXCLUDE_PANELS = {
    "DATA_PT_light",                # EEVEE's light panel below shows the same and more
    "RENDER_PT_post_processing",
    "RENDER_PT_simplify",
    "RENDER_PT_freestyle",
}
# EEVEE panels with generic settings we use: light power/size, material slots, surface and volume,
# world surface and volume, depth of field.
INCLUDE_PANELS = {
    "DATA_PT_EEVEE_light",
    "EEVEE_MATERIAL_PT_context_material",
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_MATERIAL_PT_volume",
    "EEVEE_WORLD_PT_surface",
    "EEVEE_WORLD_PT_volume",
    "DATA_PT_camera_dof",
    "DATA_PT_camera_dof_aperture",
}


def get_panels():
    """Built-in panel classes that should show for the AMCMCPPM engine.

    Some panels share one ``COMPAT_ENGINES`` set object (``NODE_DATA_PT_light`` uses
    ``DATA_PT_light``'s); a panel sharing the set of an excluded panel is excluded too.
    """
    candidates = [p for p in bpy.types.Panel.__subclasses__()
                  if isinstance(getattr(p, "COMPAT_ENGINES", None), set)]
    excluded_sets = [p.COMPAT_ENGINES for p in candidates if p.__name__ in EXCLUDE_PANELS]
    panels = []
    for panel in candidates:
        engines = panel.COMPAT_ENGINES
        if any(engines is s for s in excluded_sets):
            continue
        if "BLENDER_RENDER" in engines or panel.__name__ in INCLUDE_PANELS:
            panels.append(panel)
    return panels


# Panels outside the Render Properties.
other_classes = (AMCMCPPM_CAMERA_PT_panorama, AMCMCPPM_OBJECT_PT_ray_visibility,
                 AMCMCPPM_OBJECT_PT_lightgroup, AMCMCPPM_WORLD_PT_mist, AMCMCPPM_WORLD_PT_ambient_occlusion,
                 AMCMCPPM_WORLD_PT_ray_visibility, AMCMCPPM_WORLD_PT_light_group,
                 AMCMCPPM_VIEWLAYER_PT_passes, AMCMCPPM_VIEWLAYER_PT_light, AMCMCPPM_VIEWLAYER_PT_cryptomatte,
                 AMCMCPPM_VIEWLAYER_PT_aov, AMCMCPPM_VIEWLAYER_PT_lightgroups)


# Draw functions added to Blender's panels: (panel, function).
appended = (("OBJECT_PT_visibility", draw_shadow_catcher), ("DATA_PT_EEVEE_light", draw_light_portal))


def register():
    for cls in classes + other_classes:
        bpy.utils.register_class(cls)
    for panel in get_panels():
        panel.COMPAT_ENGINES.add(ENGINE_ID)
    for panel, function in appended:
        getattr(bpy.types, panel).append(function)


def unregister():
    for panel, function in appended:
        getattr(bpy.types, panel).remove(function)
    for panel in get_panels():
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    for cls in reversed(classes + other_classes):
        bpy.utils.unregister_class(cls)
