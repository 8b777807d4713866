"""Scenes built in code: closed-form test cases, the Cornell box and hard-light rooms.

Used by the tests, the benchmarks and ``python -m core render --builtin NAME``.
All builders return a validated :class:`~core.scene.Scene`.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..scene import (SHADOW_CATCHER, VISIBLE_CAMERA, VISIBLE_GLOSSY, VISIBLE_TRANSMISSION, Camera, Lights,
                     Materials, Scene, World)


class MeshBuilder:
    """Accumulates triangles with material ids (counter-clockwise = front)."""

    def __init__(self):
        self.tris = []
        self.mats = []
        self.normals = []

    def add_triangles(self, corners, material, normals=None):
        corners = np.asarray(corners, np.float64).reshape(-1, 3, 3)
        self.tris.append(corners)
        self.mats.append(np.full(len(corners), material, np.int32))
        if normals is None:
            e = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-300)
            normals = np.repeat(e[:, None, :], 3, axis=1)
        self.normals.append(np.asarray(normals, np.float64).reshape(-1, 3, 3))

    def add_quad(self, a, b, c, d, material):
        """Quad a-b-c-d (counter-clockwise seen from the front)."""
        self.add_triangles([[a, b, c], [a, c, d]], material)

    def add_box(self, lo, hi, material, inward=False):
        """Axis-aligned box; normals outward (or inward for a room)."""
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                      [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], np.float64)
        faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]
        for f in faces:
            q = [v[i] for i in (f[::-1] if inward else f)]
            self.add_quad(*q, material)

    def add_sphere(self, center, radius, material, n_theta=24, n_phi=48, inward=False, smooth=True):
        th = np.linspace(0, np.pi, n_theta + 1)
        ph = np.linspace(0, 2 * np.pi, n_phi + 1)
        dirs = np.stack([np.sin(th)[:, None] * np.cos(ph)[None], np.sin(th)[:, None] * np.sin(ph)[None],
                         np.cos(th)[:, None] * np.ones_like(ph)[None]], axis=-1)
        p = np.asarray(center) + radius * dirs
        a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
        na, nb, nc, nd = dirs[:-1, :-1], dirs[1:, :-1], dirs[1:, 1:], dirs[:-1, 1:]
        t1 = np.stack([a, b, c], axis=-2).reshape(-1, 3, 3)
        t2 = np.stack([a, c, d], axis=-2).reshape(-1, 3, 3)
        n1 = np.stack([na, nb, nc], axis=-2).reshape(-1, 3, 3)
        n2 = np.stack([na, nc, nd], axis=-2).reshape(-1, 3, 3)
        tris = np.concatenate([t1, t2])
        nrm = np.concatenate([n1, n2])
        # Drop the degenerate triangles at the poles.
        area = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
        keep = area > 1e-12 * radius * radius
        tris, nrm = tris[keep], nrm[keep]
        # This parametrisation's winding faces outward (so do ``dirs``); turn both for a room.
        if inward:
            tris = tris[:, ::-1]
            nrm = -nrm[:, ::-1]
        self.add_triangles(tris, material, nrm if smooth else None)

    def build(self, materials, lights=None, camera=None, world=None, smooth=False):
        tris = np.concatenate(self.tris) if self.tris else np.zeros((0, 3, 3))
        mats = np.concatenate(self.mats) if self.mats else np.zeros(0, np.int32)
        normals = np.concatenate(self.normals) if self.normals else np.zeros((0, 3, 3))
        scene = Scene(vertices=tris.reshape(-1, 3).astype(np.float32),
                      triangles=np.arange(3 * len(tris), dtype=np.int32).reshape(-1, 3),
                      material_ids=mats, materials=materials,
                      lights=lights if lights is not None else Lights.empty(),
                      camera=camera if camera is not None else Camera(),
                      world=world if world is not None else World(),
                      shading_normals=normals.astype(np.float32) if smooth else None)
        return scene.validate()


def cornell_box(resolution=(64, 64), light="area"):
    """The Cornell box (diffuse only), 2 m wide, lit by a ceiling area light facing down."""
    mats = Materials.build([
        {"name": "white", "diffuse": (0.73, 0.73, 0.73)},
        {"name": "red", "diffuse": (0.65, 0.05, 0.05)},
        {"name": "green", "diffuse": (0.12, 0.45, 0.15)},
        {"name": "lamp", "emission": (17.0, 12.0, 4.0)},
    ])
    m = MeshBuilder()
    # Room x in [-1, 1], y in [-1, 1], z in [0, 2]; the camera looks along +y from y = -3.9.
    m.add_quad((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), 0)          # floor
    m.add_quad((-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2), 0)          # ceiling
    m.add_quad((-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2), 0)            # back
    m.add_quad((-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2), 1)        # left, red
    m.add_quad((1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0), 2)            # right, green
    _add_rotated_box(m, (0.35, 0.35, 0.0), (0.6, 0.6, 0.6), -0.3, 0)
    _add_rotated_box(m, (-0.35, 0.35 - 0.05, 0.0), (0.6, 0.6, 1.2), 0.3, 0)
    lights = []
    if light == "area":
        lights.append({"kind": "area", "position": (0, 0, 1.99), "direction": (0, 0, -1),
                       "size": (0.5, 0.5), "power": (60.0, 45.0, 20.0)})
    elif light == "mesh":
        m.add_quad((-0.25, -0.25, 1.99), (-0.25, 0.25, 1.99), (0.25, 0.25, 1.99), (0.25, -0.25, 1.99), 3)
    cam = Camera.look_at((0, -3.9, 1.0), (0, 0, 1.0), lens_mm=35.0, sensor_width=36.0,
                         resolution=resolution)
    return m.build(mats, Lights.build(lights), cam)


def _add_rotated_box(m, center_xy_z, size, angle, material):
    cx, cy, z0 = center_xy_z
    sx, sy, sz = size
    before = len(m.tris)
    m.add_box((-sx / 2, -sy / 2, 0.0), (sx / 2, sy / 2, sz), material)
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    for k in range(before, len(m.tris)):
        m.tris[k] = m.tris[k] @ rot.T + np.array([cx, cy, z0])
        m.normals[k] = m.normals[k] @ rot.T


def furnace_sphere(albedo=0.5, emission=0.5, resolution=(16, 16), radius=1.0, emission_program=None):
    """Camera at the centre of a closed diffuse sphere that also emits: L = Le / (1 - albedo).

    With ``emission_program`` (``core/procedural.py``, Object coordinates = world) the radiance
    emitted is ``emission`` times the program at each point, and the sphere's irradiance stays
    uniform (any two patches of a sphere's inside see each other alike): L(x) = Le(x) +
    albedo mean(Le) / (1 - albedo), mean(Le) over the area."""
    spec = {"name": "shell", "diffuse": albedo, "emission": emission}
    m = MeshBuilder()
    m.add_sphere((0, 0, 0), radius, 0, n_theta=32, n_phi=64, inward=True, smooth=False)
    cam = Camera.look_at((0, 0, 0), (0, 1, 0), lens_mm=20.0, resolution=resolution)
    scene = m.build(Materials.build([spec]), camera=cam)
    if emission_program is None:
        return scene
    mats = Materials.build([{**spec, "emission_program": emission_program}])
    return with_one_object(scene).replace(materials=mats).validate()


def point_in_sphere(radius=1.0, albedo=0.5, power=4 * np.pi, resolution=(16, 16)):
    """A point light at the centre of a closed diffuse sphere, camera at the centre too.

    L = albedo I / (pi R^2) (1 - albedo^(B+1)) / (1 - albedo) with I = power / (4 pi) and at
    most B scattering events per photon path.
    """
    mats = Materials.build([{"name": "shell", "diffuse": albedo}])
    m = MeshBuilder()
    m.add_sphere((0, 0, 0), radius, 0, n_theta=32, n_phi=64, inward=True, smooth=False)
    lights = Lights.build([{"kind": "point", "position": (0, 0, 0), "power": power}])
    cam = Camera.look_at((0, 0, 0), (0, 1, 0), lens_mm=20.0, resolution=resolution)
    return m.build(mats, lights, cam)


def spot_over_plane(height=1.0, albedo=0.5, power=100.0, kernel_radius=0.3, resolution=(2, 2),
                    patch=0.02, up_mirror=None, mirror_reflectance=0.9):
    """A narrow spot light over a large diffuse plane; an orthographic camera sees a tiny patch
    at the foot.  The camera's gather radius is ``kernel_radius`` (set through
    ``initial_radius_px = kernel_radius_px(scene, kernel_radius)``).

    Direct only (``max_bounces=1``): at the foot, a disk kernel of radius r averages the
    irradiance to E_r = 2 I / r^2 (1 - h / sqrt(h^2 + r^2)), I = power / (4 pi), and L = albedo E_r / pi.
    With ``up_mirror`` = H the spot points up at a mirror at height H instead: a pure caustic
    with h replaced by 2 H - h and E scaled by the mirror reflectance.
    """
    mats = Materials.build([{"name": "plane", "diffuse": albedo},
                            {"name": "mirror", "mirror": mirror_reflectance}])
    m = MeshBuilder()
    big = 20.0 * height
    m.add_quad((-big, -big, 0), (big, -big, 0), (big, big, 0), (-big, big, 0), 0)
    distance = height if up_mirror is None else 2 * up_mirror - height
    # Cone just wider than the kernel, so most photons count.
    half = np.arctan(1.15 * kernel_radius / distance)
    if up_mirror is None:
        spot = {"kind": "spot", "position": (0, 0, height), "direction": (0, 0, -1)}
    else:
        spot = {"kind": "spot", "position": (0, 0, height), "direction": (0, 0, 1)}
        m.add_quad((-big, -big, up_mirror), (-big, big, up_mirror), (big, big, up_mirror),
                   (big, -big, up_mirror), 1)
    spot.update(power=power, spot_angle=2 * half, spot_blend=0.0)
    cam = Camera(world_from_camera=_look_down(0.5 * height), projection="orthographic",
                 frame=(-patch / 2, patch / 2, -patch / 2, patch / 2), resolution=resolution)
    return m.build(mats, Lights.build([spot]), cam)


def point_light_over_floor(height=1.0, radius=0.5, soft_falloff=True, albedo=0.5, power=100.0, patch=0.02):
    """A point light of ``radius`` (with or without Soft Falloff) ``height`` over a wide diffuse
    floor; an orthographic camera (2 x 2 pixels) sees a ``patch`` at its foot.  There E = I / h^2
    as a sphere, I / (h^2 + r^2) with Soft Falloff (Cycles' disk facing the receiver), I = power /
    (4 pi); a gather disc of radius R averages them over its area (``test_closed_form.py``)."""
    mats = Materials.build([{"name": "floor", "diffuse": albedo}])
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    light = {"kind": "point", "position": (0, 0, height), "power": power, "radius": radius,
             "soft_falloff": soft_falloff}
    cam = Camera(world_from_camera=_look_down(0.5 * height), projection="orthographic",
                 frame=(-patch / 2, patch / 2, -patch / 2, patch / 2), resolution=(2, 2))
    return m.build(mats, Lights.build([light]), cam)


def kernel_radius_px(scene, radius):
    """``initial_radius_px`` that gives an orthographic camera the world-space gather ``radius``."""
    fx0, fx1, _, _ = scene.camera.frame
    return radius / ((fx1 - fx0) / scene.camera.resolution[0])


def disk_irradiance(intensity, distance, radius):
    """Irradiance from a point source at ``distance`` above a plane, averaged over a disk at its foot."""
    r2 = np.asarray(radius, np.float64) ** 2
    return 2.0 * intensity / r2 * (1.0 - distance / np.sqrt(distance ** 2 + r2))


def sky_over_floor(albedo=0.5, sky=1.0, resolution=(32, 32), size=40.0, height=2.0, pitch_deg=35.0,
                   glossy_roughness=None, multiscatter=True, material=None):
    """An open diffuse floor under a constant sky, seen at a slant: L = albedo * sky everywhere.

    Nothing but the floor, so every point of its top sees the whole sky (E = pi sky).  The
    camera (lens 35 mm) looks down ``pitch_deg`` below the horizon from ``height``: the top
    rows see the floor at a grazing angle, the bottom rows more face on, so the spacing of
    the measurement points relative to the gather radius varies down the image.

    With ``glossy_roughness`` the floor is a GGX reflector of colour ``albedo`` instead (a
    white furnace when ``albedo`` is 1): with ``multiscatter`` L = sky exactly; without it
    L = sky E(mu), the single-scattering albedo at the view cosine, which is below 1.
    ``material`` (a ``Materials.build`` entry) replaces the floor's material.
    """
    if material is not None:
        mats = Materials.build([{"name": "floor", **material}])
    elif glossy_roughness is None:
        mats = Materials.build([{"name": "floor", "diffuse": albedo}])
    else:
        mats = Materials.build([{"name": "floor", "glossy": albedo, "roughness": glossy_roughness,
                                 "glossy_multiscatter": albedo if multiscatter else 0.0}])
    m = MeshBuilder()
    h = size / 2
    m.add_quad((-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0), 0)
    pitch = np.radians(pitch_deg)
    eye = np.array([0.0, -h / 2, height])
    cam = Camera.look_at(eye, eye + (0.0, np.cos(pitch), -np.sin(pitch)), lens_mm=35.0, resolution=resolution)
    return m.build(mats, camera=cam, world=World(color=np.full(3, sky, np.float32)))


def skylight_room(albedo=0.5, sky=1.0, resolution=(16, 16), size=2.0, height=2.5, opening=0.25,
                  portal=True, portal_at=None):
    """A closed room [-size, size]^2 x [0, height] lit only by a constant sky through a square opening
    [-opening, opening]^2 in its ceiling, black but for its diffuse floor, seen straight down by an
    orthographic camera over the whole floor: L = albedo sky F(x, y) (:func:`skylight_radiance`).
    With ``portal`` a light portal fills the opening (``World.portals``); ``portal_at`` (centre,
    half extents u, v) puts one there instead (on a wall, it lets no light in)."""
    mats = Materials.build([{"name": "floor", "diffuse": albedo}, {"name": "black"}])
    m = MeshBuilder()
    s, h, a = size, height, opening
    m.add_quad((-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0), 0)
    m.add_quad((-s, s, 0), (s, s, 0), (s, s, h), (-s, s, h), 1)
    m.add_quad((-s, -s, 0), (-s, -s, h), (s, -s, h), (s, -s, 0), 1)
    m.add_quad((-s, -s, 0), (-s, s, 0), (-s, s, h), (-s, -s, h), 1)
    m.add_quad((s, -s, 0), (s, -s, h), (s, s, h), (s, s, 0), 1)
    for x0, x1, y0, y1 in ((-s, s, -s, -a), (-s, s, a, s), (-s, -a, -a, a), (a, s, -a, a)):
        m.add_quad((x0, y0, h), (x0, y1, h), (x1, y1, h), (x1, y0, h), 1)
    cam = Camera(world_from_camera=_look_down(h / 2), projection="orthographic", frame=(-s, s, -s, s),
                 resolution=resolution)
    world = World(color=np.full(3, sky, np.float32))
    if portal or portal_at is not None:
        # (light crosses the opening downwards: u x v along -z)
        frame = portal_at if portal_at is not None else ((0.0, 0.0, h), (0.0, a, 0.0), (a, 0.0, 0.0))
        world.portals, world.portal_disks = np.array([frame], np.float64), np.zeros(1, bool)
    return m.build(mats, camera=cam, world=world)


def skylight_radiance(x, y, albedo=0.5, sky=1.0, height=2.5, opening=0.25):
    """The floor's radiance at (x, y) in :func:`skylight_room`: albedo sky F, F the form factor from
    the point to the opening (parallel rectangles' corner formula, signed over the four corners)."""
    def corner(dx, dy):
        p, q = np.abs(dx) / height, np.abs(dy) / height
        f = (p / np.sqrt(1 + p * p) * np.arctan(q / np.sqrt(1 + p * p))
             + q / np.sqrt(1 + q * q) * np.arctan(p / np.sqrt(1 + q * q))) / (2 * np.pi)
        return np.sign(dx) * np.sign(dy) * f
    a = opening
    form = corner(a - x, a - y) - corner(-a - x, a - y) - corner(a - x, -a - y) + corner(-a - x, -a - y)
    return albedo * sky * form


def sun_through_slab(ior=1.5, irradiance=10.0, albedo=0.5, resolution=(8, 8), fresnel=1.0):
    """A sun at normal incidence through a glass slab onto a diffuse floor, camera under the slab.

    With ``max_bounces=2`` (photons cross the two faces and land, no internal reflection):
    E_floor = E (1 - s F0)^2, F0 = ((ior - 1)/(ior + 1))^2, and L = albedo E_floor / pi, for the
    glass's share ``fresnel`` s that reflects by Fresnel (``Materials.dielectric_fresnel``).
    """
    mats = Materials.build([{"name": "floor", "diffuse": albedo},
                            {"name": "glass", "dielectric": 1.0, "ior": ior, "dielectric_fresnel": fresnel}])
    m = MeshBuilder()
    m.add_quad((-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0), 0)
    m.add_box((-0.3, -0.3, 1.0), (0.3, 0.3, 1.1), 1)
    lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": irradiance}])
    cam = Camera(world_from_camera=_look_down(0.5), projection="orthographic",
                 frame=(-0.1, 0.1, -0.1, 0.1), resolution=resolution)
    return m.build(mats, lights, cam)


def sun_through_sheet(material, irradiance=10.0, floor_albedo=None, resolution=(8, 8), half=20.0,
                      shading_normal=None):
    """A sun at normal incidence on a thin horizontal sheet (``material``, a ``Materials.build``
    entry; half-size ``half`` at z = 1, front up) and an orthographic camera at z = 0.5.

    Without a floor the camera looks up at the sheet's underside: a translucent colour T there
    shows L = T E / pi (nothing lights the underside from below).  With ``floor_albedo`` rho
    a diffuse floor lies at z = 0 and the camera looks down at it: under a sheet of diffuse
    colour D (its underside reflects the floor's light back) the floor's radiosity is
    B = rho T E / (1 - rho D) (infinite planes; the sheet's size makes the view factor 0.998),
    L = B / pi.  ``shading_normal`` (3,) gives the sheet that shading normal at every corner."""
    specs = [{"name": "sheet", **material}]
    if floor_albedo is not None:
        specs.append({"name": "floor", "diffuse": floor_albedo})
    m = MeshBuilder()
    h = half
    m.add_quad((-h, -h, 1.0), (h, -h, 1.0), (h, h, 1.0), (-h, h, 1.0), 0)
    smooth = shading_normal is not None
    if smooth:
        m.normals[-1][:] = np.asarray(shading_normal, np.float64) / np.linalg.norm(shading_normal)
    if floor_albedo is not None:
        m.add_quad((-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0), 1)
    lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": irradiance}])
    pose = _look_down(0.5)
    if floor_albedo is None:
        pose[:3, :3] = np.diag([1.0, -1.0, -1.0])          # turned over: looking straight up
    cam = Camera(world_from_camera=pose, projection="orthographic", frame=(-0.2, 0.2, -0.2, 0.2),
                 resolution=resolution)
    return m.build(Materials.build(specs), lights, cam, smooth=smooth)


def sheet_over_glowing_floor(material, emission=1.0, floor_albedo=0.8, resolution=(16, 16), half=2.0,
                             height=0.1):
    """A sheet of ``material`` (a ``Materials.build`` entry; half-size ``half``) ``height`` over a diffuse
    floor of albedo rho that also emits ``emission`` Le; an orthographic camera half-way up looks
    down at the floor, which its light reaches from the sheet after the floor's diffuse bounce (and its
    own).  For infinite planes and a sheet of diffuse albedo a, L = Le / (1 - a rho); with Cycles'
    Reflective Caustics off a Principled BSDF's sheet is one of albedo a (its diffuse part, not dimmed
    by the specular or coat layer above it, after a diffuse bounce)."""
    specs = [{"name": "sheet", **material}, {"name": "floor", "diffuse": floor_albedo, "emission": emission}]
    m = MeshBuilder()
    h = half
    m.add_quad((-h, -h, height), (h, -h, height), (h, h, height), (-h, h, height), 0)
    m.add_quad((-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0), 1)
    f = 0.5 * h
    cam = Camera(world_from_camera=_look_down(0.5 * height), projection="orthographic", frame=(-f, f, -f, f),
                 resolution=resolution)
    return m.build(Materials.build(specs), None, cam)


def sun_over_normal_mapped_floor(tangent_space_normal, sun_toward=(0.0, 0.0, 1.0), tangent=(1.0, 0.0, 0.0),
                                 sign=1.0, strength=1.0, irradiance=10.0, albedo=0.5, resolution=(8, 8),
                                 correction=True):
    """A flat diffuse floor (z = 0, uv = xy + 0.5) with a constant tangent-space normal map under a sun.

    ``tangent_space_normal`` (3,) is the map's normal (stored as (n + 1) / 2), ``tangent`` and
    ``sign`` the floor's tangent frame.  With shading normal N the floor's radiance is
    albedo E max(0, N . l) G / pi for the unit direction ``sun_toward`` l (the sun's irradiance E
    is on a plane facing it; G Cycles' bump shadowing, 1 without Bump Map ``correction``),
    whatever the camera sees from above.
    """
    n = np.asarray(tangent_space_normal, np.float64)
    tex = np.broadcast_to(((n / np.linalg.norm(n) + 1.0) / 2.0).astype(np.float32), (2, 2, 3))
    frame = np.concatenate([np.asarray(tangent, np.float32), [sign]]).astype(np.float32)
    return _sunlit_textured_floor({"normal_texture": 0, "normal_strength": strength,
                                   "bump_correction": int(correction)}, np.array(tex),
                                  sun_toward, irradiance, albedo, resolution,
                                  tangents=np.broadcast_to(frame, (2, 3, 4)))


def sun_over_bumped_floor(slope, distance=1.0, strength=1.0, sun_toward=(0.0, 0.0, 1.0), irradiance=10.0,
                          albedo=0.5, resolution=(8, 8), procedural=False):
    """A flat diffuse floor (z = 0, uv = xy + 0.5) with a bump map whose height rises by
    ``slope`` per unit of u (a grey ramp image; with ``procedural``, the program slope x of the
    Object coordinates, or with ``procedural="op"`` that height in a ``bump`` program of the
    normal, ``normal_program``), under a sun.  Cycles' Bump node then bends the normal to
    normalize(z - distance slope x) before the strength blend."""
    w = 64
    ramp = slope * (np.arange(w) + 0.5) / w
    tex = np.repeat(np.broadcast_to(ramp[None, :, None], (2, w, 1)), 3, axis=2).astype(np.float32)
    spec = {"bump_texture": 0, "bump_strength": strength, "bump_distance": distance}
    scene = _sunlit_textured_floor(spec, tex, sun_toward, irradiance, albedo, resolution)
    if not procedural:
        return scene
    x = {"op": "separate", "vector": {"op": "attribute", "name": "object"}, "output": "X"}
    height = {"op": "math", "operation": "MULTIPLY", "a": x, "b": slope}
    spec = {"name": "floor", "diffuse": albedo, "bump_program": height, "bump_strength": strength,
            "bump_distance": distance}
    if procedural == "op":
        bent = {"op": "bump", "height": height, "strength": strength, "distance": distance}
        spec = {"name": "floor", "diffuse": albedo, "normal_program": bent}
    return with_one_object(scene.replace(materials=Materials.build([spec]), textures=[])).validate()


def _sunlit_textured_floor(spec, texture, sun_toward, irradiance, albedo, resolution, tangents=None):
    """The 1 m floor of the two builders above (two triangles, uv = xy + 0.5), its diffuse
    material with the extra ``spec`` keys and image ``texture``, a sun and a camera from above."""
    m = MeshBuilder()
    m.add_quad((-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0), 0)
    l = np.asarray(sun_toward, np.float64)
    lights = Lights.build([{"kind": "sun", "direction": -l / np.linalg.norm(l), "power": irradiance}])
    cam = Camera(world_from_camera=_look_down(0.5), projection="orthographic",
                 frame=(-0.1, 0.1, -0.1, 0.1), resolution=resolution)
    scene = m.build(Materials.build([{"name": "floor", "diffuse": albedo}]), lights, cam)
    corners = scene.vertices[scene.triangles]                                   # (T, 3, 3)
    mats = Materials.build([{"name": "floor", "diffuse": albedo, **spec}])
    return scene.replace(materials=mats, uvs=corners[..., :2] + 0.5, textures=[texture],
                         tangents=tangents).validate()


def camera_in_glass(ior=1.5, emission=1.0, resolution=(16, 16)):
    """An orthographic camera inside a glass cube looks at an emitter outside a face.

    Radiance leaving the glass is not scaled by eta^2 (Cycles' convention, stop 43): L = (1 - F0)
    Le sum_k F0^(2k) (internal round trips, each two more delta bounces; the back face shows a
    black world).
    """
    mats = Materials.build([{"name": "glass", "dielectric": 1.0, "ior": ior},
                            {"name": "emitter", "emission": emission}])
    m = MeshBuilder()
    m.add_box((-1, -1, -1), (1, 1, 1), 0)
    m.add_quad((1.5, -2, -2), (1.5, -2, 2), (1.5, 2, 2), (1.5, 2, -2), 1)
    cam_m = np.eye(4)
    # Camera -Z along world +X: columns are camera x, y, z axes in world space.
    cam_m[:3, 0], cam_m[:3, 1], cam_m[:3, 2] = (0, -1, 0), (0, 0, 1), (-1, 0, 0)
    cam = Camera(world_from_camera=cam_m, projection="orthographic", frame=(-0.5, 0.5, -0.5, 0.5),
                 resolution=resolution)
    return m.build(mats, camera=cam)


def _look_down(z):
    m = np.eye(4)
    m[:3, 3] = (0, 0, z)
    return m      # camera -Z is world -Z: looking straight down


def glass_ceiling_room(resolution=(64, 48), pane=0.12, light_height=6.0, light_size=3.0, power=60000.0,
                       fog=0.0):
    """A closed room lit only through a small glass pane in its ceiling (the paper's scene 1).

    A big area light high above the roof sends only about 0.05 % of its photons through the
    pane into what the camera sees (the paper's scene had 0.022 %).  ``fog`` > 0 fills the room
    with a volume-only box that scatters that much per metre (g = 0.3) and absorbs a tenth of
    it: the light through the pane shows as a beam.
    """
    mats = Materials.build([
        {"name": "wall", "diffuse": (0.7, 0.7, 0.7)},
        {"name": "floor", "diffuse": (0.6, 0.5, 0.4)},
        {"name": "glass", "dielectric": (1, 1, 1), "ior": 1.5},
        {"name": "box", "diffuse": (0.3, 0.4, 0.7)},
        {"name": "fog", "opacity": 0.0, "volume_scattering": fog, "volume_absorption": 0.1 * fog,
         "volume_anisotropy": 0.3},
    ])
    m = MeshBuilder()
    h = pane / 2
    # Room [-2, 2] x [-2, 2] x [0, 2.5], ceiling with a square hole closed by a thin glass slab.
    m.add_quad((-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0), 1)
    for (a, b, c, d) in [((-2, 2, 0), (2, 2, 0), (2, 2, 2.5), (-2, 2, 2.5)),
                         ((-2, -2, 0), (-2, -2, 2.5), (2, -2, 2.5), (2, -2, 0)),
                         ((-2, -2, 0), (-2, 2, 0), (-2, 2, 2.5), (-2, -2, 2.5)),
                         ((2, -2, 0), (2, -2, 2.5), (2, 2, 2.5), (2, 2, 0))]:
        m.add_quad(a, b, c, d, 0)
    # Ceiling (facing down) split around the hole [-h, h]^2, and its outer side (facing up).
    for z, down in ((2.5, True), (2.6, False)):
        rects = [(-2, -2, 2, -h), (-2, h, 2, 2), (-2, -h, -h, h), (h, -h, 2, h)]
        for x0, y0, x1, y1 in rects:
            q = [(x0, y0, z), (x0, y1, z), (x1, y1, z), (x1, y0, z)]
            m.add_quad(*(q if down else q[::-1]), 0)
    # Hole sides.
    for (a, b) in [((-h, -h), (h, -h)), ((h, -h), (h, h)), ((h, h), (-h, h)), ((-h, h), (-h, -h))]:
        m.add_quad((a[0], a[1], 2.5), (b[0], b[1], 2.5), (b[0], b[1], 2.6), (a[0], a[1], 2.6), 0)
    m.add_box((-h, -h, 2.52), (h, h, 2.58), 2)
    _add_rotated_box(m, (0.6, 0.3, 0.0), (0.8, 0.8, 0.8), 0.4, 3)
    if fog > 0:
        m.add_box((-1.99, -1.99, 0.01), (1.99, 1.99, 2.49), 4)
    lights = Lights.build([{"kind": "area", "position": (0, 0, light_height), "direction": (0, 0, -1),
                            "size": (light_size, light_size), "power": power}])
    cam = Camera.look_at((-1.8, -1.8, 1.2), (0.5, 0.5, 0.6), lens_mm=18.0, resolution=resolution)
    return m.build(mats, lights, cam)


def _room_with_hole(m, size, height, hole_center_yz, hole, material):
    """Walls of the room [-size, size]^2 x [0, height] with a square hole in the wall x = +size."""
    s, h = size, height
    m.add_quad((-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0), material)            # floor
    m.add_quad((-s, -s, h), (-s, s, h), (s, s, h), (s, -s, h), material)            # ceiling
    m.add_quad((-s, s, 0), (s, s, 0), (s, s, h), (-s, s, h), material)              # back (+y)
    m.add_quad((-s, -s, 0), (-s, -s, h), (s, -s, h), (s, -s, 0), material)          # front (-y)
    m.add_quad((-s, -s, 0), (-s, s, 0), (-s, s, h), (-s, -s, h), material)          # left (-x)
    # Right wall (x = +s, facing -x) with the hole [y0, y1] x [z0, z1], as four rectangles.
    cy, cz = hole_center_yz
    y0, y1, z0, z1 = cy - hole / 2, cy + hole / 2, cz - hole / 2, cz + hole / 2
    for ya, yb, za, zb in [(-s, s, 0, z0), (-s, s, z1, h), (-s, y0, z0, z1), (y1, s, z0, z1)]:
        m.add_quad((s, ya, za), (s, ya, zb), (s, yb, zb), (s, yb, za), material)


def hole_mirror_glass(resolution=(64, 48), hole=0.15):
    """Sun through a small hole in a wall onto a mirror that throws it through a glass sphere
    onto the floor: caustics, also seen in the mirror (the paper's scene 2)."""
    mats = Materials.build([
        {"name": "wall", "diffuse": (0.7, 0.7, 0.7)},
        {"name": "mirror", "mirror": (0.95, 0.95, 0.95)},
        {"name": "glass", "dielectric": (1, 1, 1), "ior": 1.5},
    ])
    m = MeshBuilder()
    hole_c = np.array([2.0, 0.0, 1.9])
    _room_with_hole(m, 2.0, 2.5, hole_c[1:], hole, 0)
    sun_dir = np.array([-1.0, 0.05, -0.25])
    sun_dir /= np.linalg.norm(sun_dir)
    # A mirror where the beam lands near the left wall, turned to send it through the sphere.
    mirror_c = hole_c + sun_dir * (3.6 / -sun_dir[0])
    sphere_c = np.array([0.2, 0.1, 0.4])
    target = sphere_c + np.array([0.0, 0.0, 0.05])
    out = target - mirror_c
    out /= np.linalg.norm(out)
    n = out - sun_dir
    n /= np.linalg.norm(n)
    u = np.cross(n, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    a = 0.35
    corners = [mirror_c + a * (-u - v), mirror_c + a * (u - v), mirror_c + a * (u + v), mirror_c + a * (-u + v)]
    if np.dot(np.cross(corners[1] - corners[0], corners[2] - corners[0]), n) < 0:
        corners = corners[::-1]
    m.add_quad(*corners, 1)
    m.add_sphere(sphere_c, 0.35, 2, n_theta=24, n_phi=48)
    lights = Lights.build([{"kind": "sun", "direction": sun_dir, "power": 20.0, "sun_angle": 0.01}])
    cam = Camera.look_at((1.6, -1.8, 1.5), (-0.6, 0.3, 0.4), lens_mm=20.0, resolution=resolution)
    return m.build(mats, lights, cam, smooth=True)


def small_view(resolution=(64, 48), boxes=400, seed=1):
    """A long lens sees a tiny part of a large sunlit town (the paper's scene 3)."""
    rng = np.random.default_rng(seed)
    mats = Materials.build([{"name": "ground", "diffuse": (0.5, 0.5, 0.45)},
                            {"name": "building", "diffuse": (0.7, 0.6, 0.5)},
                            {"name": "glass", "dielectric": 1.0, "ior": 1.5}])
    m = MeshBuilder()
    m.add_quad((-100, -100, 0), (100, -100, 0), (100, 100, 0), (-100, 100, 0), 0)
    eye, target = np.array([30.0, -30.0, 12.0]), np.array([0.0, 0.0, 0.3])
    placed = 0
    while placed < boxes:
        c = rng.uniform(-95, 95, 2)
        w = rng.uniform(2, 8, 2)
        h = rng.uniform(3, 25)
        # Buildings stay out of the line of sight (2 m to spare) and out of a clearing of 20 m
        # around the subject, so no building hides it or shades it (shadows are at most 15 m).
        reach = 0.5 * float(np.hypot(*w)) + 2.0
        along = np.clip(np.dot(c - eye[:2], target[:2] - eye[:2]) / np.sum((target[:2] - eye[:2]) ** 2), 0, 1)
        if (np.linalg.norm(c - (eye[:2] + along * (target[:2] - eye[:2]))) < reach
                or np.linalg.norm(c - target[:2]) < 20.0 + reach):
            continue
        m.add_box((c[0] - w[0] / 2, c[1] - w[1] / 2, 0), (c[0] + w[0] / 2, c[1] + w[1] / 2, h), 1)
        placed += 1
    # The subject: a small glass ball on the ground in a clearing, seen from far away.
    m.add_box((-3, -3, 0), (3, 3, 0.02), 0)
    m.add_sphere((0.0, 0.0, 0.3), 0.3, 2, n_theta=16, n_phi=32)
    lights = Lights.build([{"kind": "sun", "direction": (-0.4, 0.3, -0.85), "power": 5.0, "sun_angle": 0.01}])
    cam = Camera.look_at(tuple(eye), tuple(target), lens_mm=600.0, resolution=resolution)
    return m.build(mats, lights, cam, smooth=True)


SUNLIT_CORNER_SUN = tuple(np.array([-0.4, 0.3, -0.85]) / np.linalg.norm([-0.4, 0.3, -0.85]))


def sunlit_corner(resolution=(24, 24), albedo=0.6, irradiance=4.0):
    """A long lens (600 mm, 42 m away, 16 degrees down) on a patch of some 3 by 9 m of a 200 m grey
    floor under a sun (direction SUNLIT_CORNER_SUN): the patch is 10^-3 of the scene's disc, the
    photons from afar's case for a focus (``core.lights.Focus``).  Radiance: albedo E cos(theta) /
    pi everywhere."""
    mats = Materials.build([{"name": "floor", "diffuse": albedo}])
    m = MeshBuilder()
    m.add_quad((-100, -100, 0), (100, -100, 0), (100, 100, 0), (-100, 100, 0), 0)
    lights = Lights.build([{"kind": "sun", "direction": SUNLIT_CORNER_SUN, "power": irradiance,
                            "sun_angle": 0.01}])
    cam = Camera.look_at((30.0, -30.0, 12.0), (0.0, 0.0, 0.0), lens_mm=600.0, resolution=resolution)
    return m.build(mats, lights, cam)


def mirror_lit_shade(resolution=(16, 16), albedo=0.6, irradiance=4.0):
    """A camera under a 16 x 16 m canopy 5 m above a 40 m ground looks at the ground under its
    middle, lit by a 6 x 3 m mirror 11 m away that throws the sun in under the canopy: a focus
    around what the camera sees aims at the canopy's top, and the light comes off the mirror,
    outside the focus sphere, which only the uniform half of the photons reach (the focus does not
    pay; ``core.lights.Focus``)."""
    mats = Materials.build([{"name": "ground", "diffuse": albedo}, {"name": "mirror", "mirror": 0.95}])
    m = MeshBuilder()
    m.add_quad((-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0), 0)
    m.add_quad((-8, -8, 5), (-8, 8, 5), (8, 8, 5), (8, -8, 5), 0)
    sun = np.array([0.0, 0.3, -1.0]) / np.linalg.norm([0.0, 0.3, -1.0])
    c = np.array([0.0, -11.0, 3.0])
    out = -c / np.linalg.norm(c)
    n = (out - sun) / np.linalg.norm(out - sun)
    t = np.array([1.0, 0.0, 0.0])
    b = np.cross(n, t)
    m.add_quad(c - 3 * t - 1.5 * b, c + 3 * t - 1.5 * b, c + 3 * t + 1.5 * b, c - 3 * t + 1.5 * b, 1)
    lights = Lights.build([{"kind": "sun", "direction": sun, "power": irradiance, "sun_angle": 0.01}])
    cam = Camera.look_at((0.0, -4.0, 1.5), (0.0, 0.0, 0.0), lens_mm=200.0, resolution=resolution)
    return m.build(mats, lights, cam)


def corner_in_world_fog(resolution=(64, 64)):
    """A floor and a wall in a world filled with fog (World.volume_*: scattering 0.14 / 0.16 /
    0.18 per metre, g = -0.2, absorbing a tenth of that), lit by a spot whose beam shows and a
    small point light; no sky (the world's volume would take it).  The camera is in the fog."""
    mats = Materials.build([{"name": "floor", "diffuse": 0.8}, {"name": "wall", "diffuse": 0.5}])
    m = MeshBuilder()
    m.add_quad((-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0), 0)
    m.add_quad((-5, 1.5, -3), (5, 1.5, -3), (5, 1.5, 3), (-5, 1.5, 3), 1)
    spot_dir = np.array([0.8, 0.5, -3.0]) / np.linalg.norm([0.8, 0.5, -3.0])
    lights = Lights.build([{"kind": "spot", "position": (-0.5, -0.5, 3.0), "direction": spot_dir,
                            "power": 800.0, "radius": 0.05, "spot_angle": np.radians(35.0),
                            "spot_blend": 0.2},
                           {"kind": "point", "position": (1.2, 0.5, 1.0), "power": 100.0, "radius": 0.1}])
    world = World(volume_scattering=np.array([0.14, 0.16, 0.18]),
                  volume_absorption=np.array([0.018, 0.012, 0.006]), volume_anisotropy=-0.2)
    cam = Camera.look_at((0, -5, 5), (0, 0, 0), lens_mm=35.0, resolution=resolution)
    return m.build(mats, lights, cam, world)


def glowing_glass_ball(resolution=(64, 48)):
    """A room lit only by a glowing gas inside a solid glass ball on its floor: every photon
    leaves through the glass (the room is lit by refracted light alone), and the camera sees the
    glow through the glass.  The gas (a sphere of radius 0.2 in a ball of
    0.35, IOR 1.5) glows orange, 20 per metre, and scatters and absorbs a little; a blue box
    and a grey ball stand in the room."""
    mats = Materials.build([{"name": "wall", "diffuse": 0.7}, {"name": "floor", "diffuse": (0.5, 0.45, 0.4)},
                            {"name": "glass", "dielectric": 1.0, "ior": 1.5},
                            {"name": "gas", "opacity": 0.0, "volume_emission": (20.0, 9.0, 3.0),
                             "volume_scattering": 1.5, "volume_absorption": 0.5, "volume_anisotropy": 0.2},
                            {"name": "box", "diffuse": (0.1, 0.2, 0.6)}])
    m = MeshBuilder()
    m.add_box((-2, -2, 0), (2, 2, 2.5), 0, inward=True)
    m.add_quad((-1.99, -1.99, 0.001), (1.99, -1.99, 0.001), (1.99, 1.99, 0.001), (-1.99, 1.99, 0.001), 1)
    m.add_sphere((0, 0.2, 0.351), 0.35, 2, n_theta=32, n_phi=64)
    m.add_sphere((0, 0.2, 0.351), 0.2, 3, n_theta=16, n_phi=32)
    _add_rotated_box(m, (0.9, 0.6, 0.0), (0.5, 0.5, 0.6), 0.5, 4)
    m.add_sphere((-0.9, 0.9, 0.3), 0.3, 0, n_theta=16, n_phi=32)
    cam = Camera.look_at((1.6, -1.8, 1.3), (0.0, 0.3, 0.3), lens_mm=24.0, resolution=resolution)
    return m.build(mats, Lights.empty(), cam, smooth=True)


BUILTIN = {"cornell_box": cornell_box, "furnace_sphere": furnace_sphere,
           "point_in_sphere": point_in_sphere, "spot_over_plane": spot_over_plane,
           "sun_through_slab": sun_through_slab, "camera_in_glass": camera_in_glass,
           "sky_over_floor": sky_over_floor,
           "glass_ceiling_room": glass_ceiling_room, "hole_mirror_glass": hole_mirror_glass,
           "small_view": small_view, "sunlit_corner": sunlit_corner, "mirror_lit_shade": mirror_lit_shade,
           "foggy_glass_ceiling_room": lambda resolution=(64, 48): glass_ceiling_room(resolution, fog=0.4),
           "corner_in_world_fog": corner_in_world_fog, "glowing_glass_ball": glowing_glass_ball}


def sun_over_procedural_floor(program, irradiance=10.0, resolution=(32, 32)):
    """The 1 m floor of :func:`sun_over_normal_mapped_floor` under a sun straight above, its
    diffuse colour the procedural ``program`` (``core/procedural.py``); object and generated
    coordinates are the world position (the floor is its own object at the origin, its texture
    space the unit square around it: generated = xy + 0.5, z 0.5), uv = xy + 0.5.  Radiance:
    colour(x) E / pi."""
    scene = _sunlit_textured_floor({}, np.ones((1, 1, 3), np.float32), (0, 0, 1), irradiance, 1.0,
                                   resolution)
    mats = Materials.build([{"name": "floor", "diffuse_program": program}])
    return with_one_object(scene.replace(materials=mats), ((0, 0, 0), (0.5, 0.5, 0))).validate()


def with_light_groups(scene):
    """``scene`` with a light group for each analytic light ("light0", ...), one for its emissive
    triangles and glowing volumes ("meshes") and one for its world ("world"): every emitter in one,
    so that their passes add up to the image (``Scene.light_groups``)."""
    n = scene.lights.count
    lights = dataclasses.replace(scene.lights, group=np.arange(n, dtype=np.int16))
    return scene.replace(lights=lights, world=dataclasses.replace(scene.world, group=n + 1),
                         light_groups=tuple(f"light{i}" for i in range(n)) + ("meshes", "world"),
                         emitter_group=np.full(scene.triangle_count, n, np.int16))


def with_shadow_catchers(scene, materials=None):
    """``scene`` with the triangles of ``materials`` (material indices; default every other one, the
    first included) shadow catchers (``SHADOW_CATCHER``), their ray visibility kept."""
    chosen = np.arange(0, scene.materials.count, 2) if materials is None else np.asarray(materials)
    vis = (np.full(scene.triangle_count, VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION, np.uint8)
           if scene.triangle_visibility is None else scene.triangle_visibility.copy())
    vis[np.isin(scene.material_ids, chosen)] |= SHADOW_CATCHER
    return scene.replace(triangle_visibility=vis)


def floor_catchers(scene):
    """``scene`` with the triangles that face up at its lowest height shadow catchers (and their
    count)."""
    p = scene.vertices[scene.triangles].astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    up = n[:, 2] > 0.9 * np.linalg.norm(n, axis=1)
    z = p[:, :, 2].mean(axis=1)
    floor = up & (z < z[up].min() + 1e-3 * max(np.ptp(p.reshape(-1, 3), axis=0).max(), 1e-9))
    vis = (np.full(scene.triangle_count, VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION, np.uint8)
           if scene.triangle_visibility is None else scene.triangle_visibility.copy())
    vis[floor] |= SHADOW_CATCHER
    return scene.replace(triangle_visibility=vis), int(floor.sum())


def with_one_object(scene, texture_space=((0, 0, 0), (1, 1, 1))):
    """``scene`` with every triangle in one object at the world's origin (Object coordinates are
    world positions) of texture space (location, size)."""
    return scene.replace(object_ids=np.zeros(scene.triangle_count, np.int32),
                         object_from_world=np.eye(3, 4)[None],
                         texture_spaces=np.array([texture_space], float))


def subdivide(scene, levels):
    """The same surfaces with every triangle split into 4**levels (midpoint subdivision).

    Light transport is unchanged (flat triangles stay in their plane; per-corner shading
    normals and UVs are interpolated linearly, as the renderer does), only rays cost more.
    """
    corners = scene.triangle_corners().astype(np.float64)                    # (T, 3, 3)
    extra = [a.astype(np.float64) for a in (scene.shading_normals, scene.uvs) if a is not None]
    mats = scene.material_ids
    for _ in range(levels):
        def split(c):
            m01, m12, m20 = 0.5 * (c[:, 0] + c[:, 1]), 0.5 * (c[:, 1] + c[:, 2]), 0.5 * (c[:, 2] + c[:, 0])
            return np.concatenate([np.stack(t, axis=1) for t in
                                   ((c[:, 0], m01, m20), (m01, c[:, 1], m12), (m20, m12, c[:, 2]),
                                    (m01, m12, m20))])
        corners, extra, mats = split(corners), [split(a) for a in extra], np.tile(mats, 4)
    it = iter(extra)
    return dataclasses.replace(
        scene, vertices=corners.reshape(-1, 3).astype(np.float32),
        triangles=np.arange(corners.shape[0] * 3, dtype=np.int32).reshape(-1, 3), material_ids=mats,
        shading_normals=next(it).astype(np.float32) if scene.shading_normals is not None else None,
        uvs=next(it).astype(np.float32) if scene.uvs is not None else None).validate()
