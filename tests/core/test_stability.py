"""Hard cases stay numerically stable: every image of every pass is finite and non-negative.

Each scene below is built to provoke a known failure of photon mappers or MCMC
samplers (testing.md 2e): endless specular bounces, trapped light, far-from-origin
and tiny coordinates, grazing views, degenerate emitters, extreme values and
parameter edges.  Both methods and every low-dimension mutation mode run on each (the
modes other than the default in the slow tier).
"""
import dataclasses

import numpy as np
import pytest

from core import Camera, Lights, Materials, RenderSettings, bsdf, render
from core.light_passes import LIGHT_PASSES, LIGHTGROUP_PREFIX
from core.scene import HOLDOUT_OBJECT, VISIBLE_CAMERA, World
from core.testing.scenes import MeshBuilder, with_light_groups, with_one_object, with_shadow_catchers

RUN = dict(passes=2, photons_per_pass=6000, chains=512, workers=1, max_bounces=12)


def _cam(eye, target, res=(12, 10), **kw):
    return Camera.look_at(eye, target, resolution=res, **kw)


def parallel_mirrors():
    mats = Materials.build([{"name": "mirror", "mirror": 1.0}, {"name": "floor", "diffuse": 0.5}])
    m = MeshBuilder()
    m.add_quad((-1, -5, -5), (-1, 5, -5), (-1, 5, 5), (-1, -5, 5), 0)      # facing +x
    m.add_quad((1, -5, -5), (1, -5, 5), (1, 5, 5), (1, 5, -5), 0)          # facing -x
    m.add_quad((-1, -5, -1), (1, -5, -1), (1, 5, -1), (-1, 5, -1), 1)
    return m.build(mats, Lights.build([{"kind": "point", "position": (0, 0, 0), "power": 50}]),
                   _cam((0.5, -3, 0.5), (-1, 2, -0.5)))


def light_trapped_in_glass():
    mats = Materials.build([{"name": "glass", "dielectric": 1.0, "ior": 2.4}, {"name": "floor", "diffuse": 0.7}])
    m = MeshBuilder()
    m.add_box((-0.5, -0.5, 0.01), (0.5, 0.5, 1.0), 0)
    m.add_quad((-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0), 1)
    return m.build(mats, Lights.build([{"kind": "point", "position": (0.3, 0.2, 0.6), "power": 100}]),
                   _cam((2, -2, 1.5), (0, 0, 0.4)))


def camera_inside_glass_sphere():
    mats = Materials.build([{"name": "glass", "dielectric": (0.9, 1, 0.8), "ior": 1.5},
                            {"name": "floor", "diffuse": 0.6}])
    m = MeshBuilder()
    m.add_sphere((0, 0, 1), 0.8, 0, n_theta=16, n_phi=32)
    m.add_quad((-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0), 1)
    return m.build(mats, Lights.build([{"kind": "sun", "direction": (0.3, 0.1, -1), "power": 3}]),
                   _cam((0, 0, 1), (0, 1, 0.5)), smooth=True)


def cornell_like(scale=1.0, offset=(0.0, 0.0, 0.0), ground=0.0, far=0.0):
    """A closed room lit by a glowing quad under its ceiling, ``scale`` m wide and high, at ``offset``;
    with ``ground`` a black plane of that half-width under it, with ``far`` a black box of its size
    that far along x (neither seen nor lit: they only stretch the scene's box)."""
    o = np.asarray(offset, np.float64)
    mats = Materials.build([{"name": "wall", "diffuse": 0.7}, {"name": "lamp", "emission": 5.0},
                            {"name": "black", "diffuse": 0.0}])
    m = MeshBuilder()
    m.add_box(o + scale * np.array([-1, -1, 0]), o + scale * np.array([1, 1, 2]), 0, inward=True)
    c = o + scale * np.array([0, 0, 1.98])
    h = 0.3 * scale
    m.add_quad(c + (-h, -h, 0), c + (-h, h, 0), c + (h, h, 0), c + (h, -h, 0), 1)
    if ground:
        z = o[2] - 0.5 * scale
        m.add_quad(o + (-ground, -ground, z), o + (ground, -ground, z), o + (ground, ground, z),
                   o + (-ground, ground, z), 2)
    if far:
        away = o + (far, 0, 0)
        m.add_box(away + scale * np.array([-1, -1, 0]), away + scale * np.array([1, 1, 2]), 2)
    return m.build(mats, camera=_cam(o + scale * np.array([0, -0.9, 1]), o + scale * np.array([0, 1, 0.8])))


def grazing_view():
    # (a rough diffuse floor: its Oren-Nayar terms at cosines near 0 on both sides)
    mats = Materials.build([{"name": "floor", "diffuse": 0.8, "diffuse_roughness": 1.0}])
    m = MeshBuilder()
    m.add_quad((-100, -100, 0), (100, -100, 0), (100, 100, 0), (-100, 100, 0), 0)
    # Camera 1 mm above the plane, looking along it (89.97 degrees from the normal).
    return m.build(mats, Lights.build([{"kind": "sun", "direction": (0.0, 0.999, -0.045), "power": 10}]),
                   _cam((0, 0, 0.001), (0, 2, 0)))


def degenerate_emitters():
    mats = Materials.build([{"name": "floor", "diffuse": 0.5}, {"name": "lamp", "emission": 1e3},
                            {"name": "black", "emission": 0.0}])
    m = MeshBuilder()
    m.add_quad((-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0), 0)
    m.add_triangles([[(0, 0, 1), (0, 0, 1), (0, 0, 1)]], 1)                # zero area, emissive
    m.add_triangles([[(0, 0, 1.5), (1e-7, 0, 1.5), (0, 1e-7, 1.5)]], 1)     # tiny, very bright
    m.add_triangles([[(0, 1, 1), (1, 1, 1), (0, 2, 1)]], 2)                 # black emitter
    return m.build(mats, camera=_cam((0, -3, 2), (0, 0, 0)))


def extreme_values():
    # The glossy boxes are metals whose F82 curve is out of all bounds (saturated to [0, 1]); the
    # floor reflects all it gets and lets as much through (a gain of 2).  Light profiles: one hot
    # cell of 1e6 in zeros (the 1e12 W point light), all zeros (a spot), and a tiny disk's.
    mats = Materials.build([{"name": "floor", "diffuse": 1.0, "translucent": 1.0},
                            {"name": "rough", "glossy": 1.0, "roughness": 1.0, "glossy_metal_rise": 1e30,
                             "glossy_metal_dip": -1e30},
                            {"name": "sharp", "glossy": 1.0, "roughness": 0.0, "glossy_metal_dip": 1e30},
                            {"name": "ior1", "dielectric": 1.0, "ior": 1.0}, {"name": "black"}])
    m = MeshBuilder()
    m.add_quad((-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0), 0)
    m.add_box((-1.5, -0.5, 0), (-0.5, 0.5, 1), 1)
    m.add_box((0.5, -0.5, 0), (1.5, 0.5, 1), 2)
    m.add_box((-0.5, 1, 0), (0.5, 2, 1), 3)
    m.add_box((-0.5, -2, 0), (0.5, -1, 1), 4)
    lights = Lights.build([
        {"kind": "point", "position": (0, 0, 3), "power": 1e12},
        {"kind": "spot", "position": (1, 1, 3), "direction": (0, 0, -1), "power": 100, "spot_angle": 0.0},
        {"kind": "spot", "position": (-1, 1, 3), "direction": (0, 0, -1), "power": 100, "spot_angle": np.pi,
         "spot_blend": 1.0},
        {"kind": "sun", "direction": (0, 0.2, -1), "power": 1.0, "sun_angle": np.pi},
        {"kind": "disk", "position": (0, 0, 2.5), "direction": (0, 0, -1), "size": (1e-9, 1e-9), "power": 5,
         "profile": 0},
        {"kind": "spot", "position": (0.5, 0, 3), "direction": (0, 0, -1), "power": 100, "profile": 1},
    ])
    lights.profile[0] = 0
    profiles = np.zeros((2, 19, 37), np.float32)
    profiles[0, 3, 5] = 1e6
    lights.profiles = profiles
    lights.axis_u[[0, 5]], lights.axis_v[[0, 5]] = (1, 0, 0), (0, 1, 0)
    cam = _cam((0, -5, 3), (0, 0, 0.5), aperture_radius=0.5, focus_distance=1e-3)
    return m.build(mats, lights, cam)


def extreme_microfacets():
    """Beckmann microfacets (stop 46) at their edges: glossy and glass of roughness 1 and just
    above the mirror's 0.02, stretched 100 and 0.01, glass of IOR 1.0001 and 3.8, a Refraction
    BSDF's (no Fresnel reflection), a grazing sun and a camera just above the floor."""
    beck = bsdf.DISTRIBUTION_BECKMANN
    mats = Materials.build([
        {"name": "floor", "glossy": 0.9, "roughness": 1.0, "glossy_distribution": beck,
         "glossy_stretch": 100.0},
        {"name": "sharp", "glossy": 0.9, "roughness": 0.021, "glossy_distribution": beck,
         "glossy_stretch": 0.01},
        {"name": "frosted", "dielectric": 1.0, "ior": 3.8, "dielectric_roughness": 1.0,
         "dielectric_distribution": beck},
        {"name": "thin", "dielectric": 1.0, "ior": 1.0001, "dielectric_roughness": 0.021,
         "dielectric_distribution": beck, "dielectric_fresnel": 0.0},
        {"name": "wall", "diffuse": 0.5, "glossy": 0.5, "roughness": 0.5, "glossy_distribution": beck,
         "glossy_metal_rise": 1e30, "glossy_metal_dip": -1e30}])
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    m.add_box((-1.5, -0.5, 0), (-0.5, 0.5, 1), 1)
    m.add_box((0.5, -0.5, 0), (1.5, 0.5, 1), 2)
    m.add_box((-0.5, 1, 0), (0.5, 2, 1), 3)
    m.add_quad((-20, 3, 0), (20, 3, 0), (20, 3, 5), (-20, 3, 5), 4)
    lights = Lights.build([{"kind": "sun", "direction": (0.0, 0.999, -0.045), "power": 10},
                           {"kind": "point", "position": (0, 0, 3), "power": 1e4}])
    return m.build(mats, lights, _cam((0, -5, 0.01), (0, 1, 0.3)))


def wild_procedural_colour():
    """A room whose walls' colour and lamp's emission are a program gone wild: 1 / x (up to 1e7
    near the plane x = 0, negative beyond it), to the power 40, times a noise: the colours are
    clamped (to 100, the emission to 1e30), the image finite.  The walls' bump height and glossy
    roughness overflow too (inf, and NaN from the tangent of inf)."""
    room = cornell_like()
    x = {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}
    wild = {"op": "math", "operation": "POWER", "a": {"op": "math", "operation": "DIVIDE", "a": 1.0, "b": x},
            "b": 40.0}
    noise = {"op": "noise", "vector": {"op": "attribute", "name": "object"}, "scale": 3.0, "output": "Color"}
    program = {"op": "mix_color", "blend": "MULTIPLY", "fac": 1.0, "a": {"op": "splat", "value": wild},
               "b": noise}
    # Overflowing heights and roughness: exp(1000 x) is inf beyond x = 0.71, its tangent NaN there.
    scaled = {"op": "math", "operation": "MULTIPLY", "a": x, "b": 1000.0}
    blowup = {"op": "math", "operation": "EXPONENT", "a": scaled}
    tangent = {"op": "math", "operation": "TANGENT", "a": blowup}
    height = {"op": "vector_math", "operation": "DOT_PRODUCT", "output": "Value",
              "a": {"op": "splat", "value": tangent}, "b": [1, -1, 1]}
    mats = Materials.build([{"name": "wall", "diffuse_program": program, "bump_program": height,
                             "glossy": 0.5, "roughness_program": blowup},
                            {"name": "lamp", "emission": 5.0, "emission_program": program}])
    return with_one_object(room.replace(materials=mats)).validate()


def transparent_stack():
    """The room cut by 100 parallel veils between the lamp and the floor, each of an opacity that
    1 / x makes 0 to 1 and wild in between (a value the program clamps), and the camera looking
    through all of them: rays cross at most 64 and stop on the next.  The veils are half
    holdouts, and the lamp a holdout object: the pixels lose alpha through 64 crossings."""
    room = cornell_like()
    x = {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}
    wild = {"op": "math", "operation": "DIVIDE", "a": 0.01, "b": x}
    specs = [{"name": "wall", "diffuse": 0.7}, {"name": "lamp", "emission": 5.0},
             {"name": "veil", "diffuse": 0.5}]
    m = MeshBuilder()
    m.tris, m.mats = [room.triangle_corners()], [room.material_ids]
    m.normals = [np.zeros((room.triangle_count, 3, 3))]
    for z in np.linspace(0.1, 1.9, 100):
        m.add_quad((-1, -1, z), (1, -1, z), (1, 1, z), (-1, 1, z), 2)
    plain = [{k: v for k, v in s.items() if k != "diffuse_program"} for s in specs]
    scene = m.build(Materials.build(plain), camera=room.camera)
    specs[2] = {**specs[2], "opacity_program": wild, "transparent_color": (1.0, 0.9, 0.8), "holdout": 0.5}
    flags = np.where(scene.material_ids == 1, 7 | HOLDOUT_OBJECT, 7).astype(np.uint8)
    return with_one_object(scene).replace(materials=Materials.build(specs),
                                          triangle_visibility=flags).validate()


def extreme_coats():
    """The room's walls, lamp and two boxes under extreme coats: IOR 1 (a coat that reflects
    nothing) with a black tint over the walls, a coat of IOR 1e6 and roughness 1 over a glass box,
    a sharp coat over a mirror box, a coat of weight 1e-8 over the lamp, and a roughness map under a
    coat on the floor."""
    room = cornell_like()
    wild = {"op": "math", "operation": "DIVIDE", "a": 0.01,
            "b": {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}}
    specs = [{"name": "wall", "diffuse": 0.7, "coat": 1.0, "coat_ior": 1.0, "coat_tint": 0.0, "glossy": 0.5},
             {"name": "lamp", "emission": 5.0, "coat": 1e-8, "coat_tint": (1.0, 0.0, 1e-30)},
             {"name": "glass", "dielectric": 1.0, "coat": 1.0, "coat_ior": 1e6, "coat_roughness": 1.0},
             {"name": "mirror", "mirror": 1.0, "coat": 1.0, "coat_roughness": 0.0}]
    m = MeshBuilder()
    m.tris, m.mats = [room.triangle_corners()], [room.material_ids]
    m.normals = [np.zeros((room.triangle_count, 3, 3))]
    m.add_box((-0.7, -0.3, 0), (-0.1, 0.3, 0.8), 2)
    m.add_box((0.2, -0.2, 0), (0.7, 0.3, 1.2), 3)
    plain = [{k: v for k, v in s.items() if k != "diffuse_program"} for s in specs]
    scene = m.build(Materials.build(plain), camera=room.camera)
    specs[0] = {**specs[0], "roughness_program": wild}
    return with_one_object(scene).replace(materials=Materials.build(specs)).validate()


def extreme_volumes():
    """The room (walls and lamp) inside a volume-only box that also holds the camera, with
    absorbing boxes in it: glass absorbing 1e30 per metre, a volume-only box absorbing 1e-30 in
    one channel and 1e6 in another around the lamp, a single open quad that absorbs (no inside),
    and a glass box nested in a volume-only one, both absorbing.  Some glow: the box around the
    lamp 1e6 per metre in the channel it hardly absorbs, the open quad (no volume: no photons), a
    box of 1 micrometre glowing 1e12 that scatters 1e3, and a box whose faces point inwards
    (its inside is outside)."""
    room = cornell_like()
    specs = [{"name": "wall", "diffuse": 0.7}, {"name": "lamp", "emission": 5.0},
             {"name": "air", "opacity": 0.0, "volume_absorption": 0.05},
             {"name": "dark glass", "dielectric": 1.0, "volume_absorption": 1e30},
             {"name": "gas", "opacity": 0.0, "volume_absorption": (1e-30, 1e6, 0.0),
              "volume_emission": (1e6, 1e-30, 0.0)},
             {"name": "sheet", "diffuse": 0.5, "opacity": 0.5, "volume_absorption": 3.0,
              "volume_emission": 2.0},
             {"name": "inner glass", "dielectric": 1.0, "ior": 1.33, "volume_absorption": (0.0, 2.0, 9.0)},
             {"name": "ember", "opacity": 0.0, "volume_emission": 1e12, "volume_scattering": 1e3},
             {"name": "inside out", "opacity": 0.0, "volume_emission": 1.0}]
    m = MeshBuilder()
    m.tris, m.mats = [room.triangle_corners()], [room.material_ids]
    m.normals = [np.zeros((room.triangle_count, 3, 3))]
    m.add_box((-1.5, -1.5, -0.5), (1.5, 1.5, 2.5), 2)
    m.add_box((-0.7, -0.3, 0), (-0.1, 0.3, 0.8), 3)
    m.add_box((-0.4, -0.4, 1.8), (0.4, 0.4, 1.99), 4)
    m.add_quad((0.1, -0.5, 0.3), (0.9, -0.5, 0.3), (0.9, 0.5, 0.3), (0.1, 0.5, 0.3), 5)
    m.add_box((0.2, -0.2, 0.5), (0.7, 0.3, 1.2), 4)
    m.add_box((0.3, -0.1, 0.6), (0.6, 0.2, 1.1), 6)
    m.add_box((0.0, 0.0, 1.0), (1e-6, 1e-6, 1.000001), 7)
    m.add_box((-0.9, 0.5, 0.1), (-0.5, 0.9, 0.5), 8, inward=True)
    return m.build(Materials.build(specs), camera=room.camera)


def extreme_scattering():
    """The room inside a fog box that also holds the camera and scatters almost straight on
    (g = 0.99), with scattering boxes in it: one scattering 1e6 per metre around the lamp, one
    scattering 1e-30 in one channel and 1e3 in another almost straight back (g = -0.99), a
    glass box that scatters inside, an open quad that scatters (no inside), and a scattering
    box nested in the glass one."""
    room = cornell_like()
    specs = [{"name": "wall", "diffuse": 0.7}, {"name": "lamp", "emission": 5.0},
             {"name": "fog", "opacity": 0.0, "volume_scattering": 0.5, "volume_anisotropy": 0.99},
             {"name": "dense", "opacity": 0.0, "volume_scattering": 1e6, "volume_absorption": 1.0},
             {"name": "odd", "opacity": 0.0, "volume_scattering": (1e-30, 1e3, 0.0),
              "volume_anisotropy": -0.99},
             {"name": "milky glass", "dielectric": 1.0, "volume_scattering": 5.0, "volume_absorption": 0.1},
             {"name": "veil", "diffuse": 0.3, "opacity": 0.5, "volume_scattering": 3.0}]
    m = MeshBuilder()
    m.tris, m.mats = [room.triangle_corners()], [room.material_ids]
    m.normals = [np.zeros((room.triangle_count, 3, 3))]
    m.add_box((-1.5, -1.5, -0.5), (1.5, 1.5, 2.5), 2)
    m.add_box((-0.4, -0.4, 1.8), (0.4, 0.4, 1.99), 3)
    m.add_box((-0.7, -0.3, 0), (-0.1, 0.3, 0.8), 4)
    m.add_box((0.2, -0.2, 0.5), (0.7, 0.3, 1.2), 5)
    m.add_box((0.3, -0.1, 0.6), (0.6, 0.2, 1.1), 4)
    m.add_quad((0.1, -0.5, 0.3), (0.9, -0.5, 0.3), (0.9, 0.5, 0.3), (0.1, 0.5, 0.3), 6)
    return m.build(Materials.build(specs), camera=room.camera)


def extreme_world_volume():
    """The scattering extremes of :func:`extreme_scattering` inside a world whose volume scatters
    1e-30 per metre in red, 50 in green and not at all in blue, almost straight back (g = -0.99),
    and absorbs 1e6 in blue: the camera and the lamp sit in its densest channel, a sun and a sky
    come through in blue alone, a point light of radius 0.1 is seen by the camera, and the room
    is opened by a missing wall (rays leave into the unbounded fog)."""
    scene = extreme_scattering()
    keep = np.flatnonzero(~np.all(scene.triangle_corners()[:, :, 1] > 0.999, axis=1))   # the wall y = 1
    m = MeshBuilder()
    m.tris, m.mats = [scene.triangle_corners()[keep]], [scene.material_ids[keep]]
    m.normals = [np.zeros((len(keep), 3, 3))]
    lights = Lights.build([{"kind": "sun", "direction": (0.3, 0.2, -1.0), "power": 5.0, "angle": 0.1},
                           {"kind": "point", "position": (0.5, 0.5, 1.5), "power": 50.0, "radius": 0.1,
                            "visibility": VISIBLE_CAMERA}])
    world = World(color=np.full(3, 0.5, np.float32), volume_scattering=np.array([1e-30, 50.0, 0.0]),
                  volume_absorption=np.array([0.0, 0.0, 1e6]), volume_anisotropy=-0.99)
    return m.build(scene.materials, lights, scene.camera, world)


def extreme_subsurface():
    """Boxes in the room scattering beneath their surfaces at the inputs' edges (stop 45): a white
    medium (albedo 1: walks that only end at the surface or after the 256 steps), radii of 1e-30,
    1 and 1e6 in one material, a black one, anisotropy 0.9 with an IOR of 3.8 and a smooth entry
    (alpha 0), Skin at IOR 1.01, a medium nested in a glass box, an open quad (walks under it
    never meet a surface again), a box of 1e-6 and a texture on the colour gone wild (1 / x); each
    box its own object (a walk meets its own object's faces alone), the room another."""
    room = cornell_like()
    wild = {"op": "splat", "value": {"op": "math", "operation": "DIVIDE", "a": 0.01,
                                     "b": {"op": "separate", "vector": {"op": "attribute", "name": "object"},
                                           "output": "X"}}}
    specs = [{"name": "wall", "diffuse": 0.7}, {"name": "lamp", "emission": 5.0},
             {"name": "mixed radii", "diffuse": 0.8, "subsurface_weight": 1.0,
              "subsurface_radius": (1e-30, 1.0, 1e6), "glossy": 0.5, "roughness": 0.3},
             {"name": "black", "diffuse": 0.0, "subsurface_weight": 1.0, "subsurface_radius": 0.1},
             {"name": "forward", "diffuse": 0.9, "subsurface_weight": 1.0, "subsurface_radius": 0.2,
              "subsurface_anisotropy": 0.9, "subsurface_ior": 3.8, "subsurface_alpha": 0.0},
             {"name": "skin", "diffuse": (0.9, 0.5, 0.3), "subsurface_weight": 0.5, "subsurface_radius": 0.05,
              "subsurface_ior": 1.01, "subsurface_method": 1},
             {"name": "glass", "dielectric": 1.0},
             {"name": "wild", "diffuse": 0.5, "diffuse_program": wild, "subsurface_weight": 1.0,
              "subsurface_radius": 0.2},
             {"name": "white", "diffuse": 1.0, "subsurface_weight": 1.0, "subsurface_radius": 0.3}]
    m = MeshBuilder()
    m.tris, m.mats = [room.triangle_corners()], [room.material_ids]
    m.normals = [np.zeros((room.triangle_count, 3, 3))]
    m.add_box((-0.7, -0.3, 0), (-0.1, 0.3, 0.8), 2)
    m.add_box((0.2, -0.2, 0.0), (0.7, 0.3, 0.4), 8)
    m.add_box((0.75, 0.5, 0.0), (0.95, 0.7, 0.2), 3)
    m.add_box((0.2, -0.2, 0.5), (0.7, 0.3, 1.2), 6)
    m.add_box((0.3, -0.1, 0.6), (0.6, 0.2, 1.1), 4)
    m.add_quad((-0.9, -0.6, 1.3), (-0.3, -0.6, 1.3), (-0.3, 0.0, 1.3), (-0.9, 0.0, 1.3), 5)
    m.add_box((0.0, 0.0, 1.0), (1e-6, 1e-6, 1.000001), 4)
    m.add_box((-0.9, 0.4, 0.0), (-0.5, 0.8, 0.4), 7)
    plain = [{k: v for k, v in s.items() if k != "diffuse_program"} for s in specs]
    scene = m.build(Materials.build(plain), camera=room.camera)
    # (an object per box of 12 triangles, the quad's 2 with the room's)
    objects = np.zeros(scene.triangle_count, np.int32)
    first = room.triangle_count
    sizes = [12, 12, 12, 12, 12, 2, 12, 12]
    for i, (start, size) in enumerate(zip(np.cumsum([first] + sizes[:-1]), sizes)):
        objects[start:start + size] = 0 if size == 2 else i + 1
    count = len(sizes) + 1
    return scene.replace(materials=Materials.build(specs), object_ids=objects,
                         object_from_world=np.tile(np.eye(3, 4), (count, 1, 1)),
                         texture_spaces=np.tile([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], (count, 1, 1))).validate()


SCENES = {"parallel_mirrors": parallel_mirrors, "extreme_coats": extreme_coats,
          "extreme_volumes": extreme_volumes, "extreme_scattering": extreme_scattering,
          "extreme_world_volume": extreme_world_volume, "extreme_subsurface": extreme_subsurface,
          "wild_procedural_colour": wild_procedural_colour,
          "transparent_stack": transparent_stack,
          "light_trapped_in_glass": light_trapped_in_glass,
          "camera_inside_glass_sphere": camera_inside_glass_sphere,
          "tiny_scale": lambda: cornell_like(scale=1e-4),
          "far_from_origin": lambda: cornell_like(scale=1.0, offset=(1e5, -2e5, 3e4)),
          "grazing_view": grazing_view, "degenerate_emitters": degenerate_emitters,
          "extreme_values": extreme_values, "extreme_microfacets": extreme_microfacets}


# The chains' other mutation modes share all but their mutation with the default (exact): they run in
# the slow tier (make test's budget).
SLOW = pytest.mark.slow


@pytest.mark.parametrize("mode", [dict(method="ppm"),
                                  pytest.param(dict(method="amcmcppm", mutation="off"), marks=SLOW),
                                  pytest.param(dict(method="amcmcppm", mutation="paper"), marks=SLOW),
                                  dict(method="amcmcppm", mutation="exact")],
                         ids=["ppm", "mcmc-off", "mcmc-paper", "mcmc-exact"])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_hard_case_stays_finite(name, mode):
    def check(result):
        img = result.image
        assert np.isfinite(img).all(), f"non-finite pixels after pass {result.passes}"
        assert (img >= 0).all()
        for key, value in result.stats[-1].items():
            if isinstance(value, float):
                assert np.isfinite(value), key

    result = render(SCENES[name](), RenderSettings(**RUN, **mode), on_iteration=check)
    assert result.passes == RUN["passes"]
    assert not any("non-finite" in w for w in result.warnings), result.warnings


def test_scaled_and_shifted_rooms_agree():
    """The same room at 1e-4 scale, and 2 km and 200 km from the origin, renders to the same mean
    (ray offsets and grid keys scale with the coordinates; embree sees the scene centred)."""
    settings = RenderSettings(method="ppm", passes=4, photons_per_pass=30_000, workers=1, max_bounces=12)
    means = [render(cornell_like(**kw), settings).image[..., :3].mean()
             for kw in (dict(), dict(scale=1e-4), dict(offset=(2e3, -1e3, 5e2)),
                        dict(offset=(1e5, -2e5, 3e4)))]
    assert np.ptp(means) < 0.05 * np.mean(means), means


@pytest.mark.parametrize("stretch", [dict(ground=1e3), dict(far=1e3), dict(far=1e12)],
                         ids=["huge-ground", "object-1km-away", "object-1e12-away"])
def test_a_small_room_renders_the_same_in_a_huge_scene(stretch):
    """A room 0.2 mm wide beside a black ground plane 2 km wide, or a black box 1 km or 1e12 m away,
    renders as it does alone, block by block (Cycles' float32 about the origin sees it so; offsets
    once a share of the scene's size were the room's own, and embree's frame about the box's centre
    rounded it to 0.06 mm at 1 km and lost it further)."""
    settings = RenderSettings(method="ppm", passes=4, photons_per_pass=30_000, workers=1, max_bounces=12)
    alone, stretched = (render(cornell_like(scale=1e-4, **kw), settings).image[..., :3].mean(axis=2)
                        for kw in ({}, stretch))
    blocks = [img.reshape(2, img.shape[0] // 2, 3, img.shape[1] // 3).mean(axis=(1, 3))
              for img in (alone, stretched)]
    assert np.abs(blocks[1] / blocks[0] - 1).max() < 0.05, blocks


@pytest.mark.parametrize("name", sorted(SCENES))
def test_hard_case_light_passes_stay_finite_and_add_up(name):
    """The same hard cases by the chains with every light pass, the Ambient Occlusion pass and every
    emitter in a light group of its own kind (``with_light_groups``): after every pass each of them
    is finite and not negative, and the light passes put together as Blender's compositor does make
    the image where it stays within float32, as do the groups' passes (the light passes'
    bookkeeping under mirrors facing each other, extreme values, degenerate emitters, scales of 1e-4
    and 1e5, with the groups' copies of the pairs beside the moves to the light passes' blocks, on
    the chains' paths, glowing volumes, lights seen through glass and fog, the world; a colour
    sampled instead of estimated once dropped a glossy pass at the first pass)."""
    scene = with_light_groups(SCENES[name]())
    groups = tuple(LIGHTGROUP_PREFIX + g for g in scene.light_groups)

    def check(result):
        data = result.data
        for key in LIGHT_PASSES + ("ao",) + groups:
            assert np.isfinite(data[key]).all() and (data[key] >= 0).all(), (key, result.passes)
        data = {key: value.astype(np.float64) for key, value in data.items()}
        rgb = data["emission"] + data["environment"] + data["volume_direct"] + data["volume_indirect"]
        for kind in ("diffuse", "glossy", "transmission"):
            rgb = rgb + (data[f"{kind}_direct"] + data[f"{kind}_indirect"]) * data[f"{kind}_color"]
        image = result.image[..., :3].astype(np.float64)
        kept = image < 1e37            # (sums beyond float32 stay at its largest, image and passes alike)
        if scene.world.film_transparent:    # (Environment and the world's group show it on such a film)
            kept &= result.image[..., 3:] == 1.0
        scale = max(1.0, float(image[kept].max(initial=0.0)))
        assert np.allclose(rgb[kept], image[kept], rtol=1e-4, atol=1e-6 * scale), result.passes
        total = sum(data[key] for key in groups)
        assert np.allclose(total[kept], image[kept], rtol=1e-4, atol=1e-6 * scale), result.passes

    settings = RenderSettings(**RUN, method="amcmcppm", data_passes=LIGHT_PASSES + ("ao",) + groups)
    assert render(scene, settings, on_iteration=check).passes == RUN["passes"]


@pytest.mark.parametrize("name", sorted(SCENES))
def test_hard_case_shadow_catchers_stay_finite(name):
    """The same hard cases by the chains with the objects of every other material shadow catchers
    (``with_shadow_catchers``: mirrors, glass, emitters, volumes' boundaries and fog among them) and
    the Shadow Catcher pass (every other case on a transparent film): after every pass the image
    (the catchers' matte) and the pass are finite and not negative, the alpha within [0, 1] (the
    catchers' second render and its pair in the main scene, ``CatcherRender``, under the same
    extremes)."""
    scene = with_shadow_catchers(SCENES[name]())
    transparent = sorted(SCENES).index(name) % 2 == 1

    def check(result):
        image, shadow = result.image, result.data["shadow_catcher"]
        assert np.isfinite(image).all() and (image >= 0).all(), result.passes
        assert np.isfinite(shadow).all() and (shadow >= 0).all(), result.passes
        assert (image[..., 3] <= 1.0).all(), result.passes

    world = dataclasses.replace(scene.world, film_transparent=transparent)
    settings = RenderSettings(**RUN, method="amcmcppm", data_passes=("shadow_catcher",))
    assert render(scene.replace(world=world), settings, on_iteration=check).passes == RUN["passes"]

