"""Scenes built in code: closed-form test cases, the Cornell box and hard-light rooms.

Used by the tests, the benchmarks and ``python -m core render --builtin NAME``.
All builders return a validated :class:`~core.scene.Scene`.
"""
from __future__ import annotations

import numpy as np

from ..scene import Camera, Lights, Materials, Scene, World


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
        # Orient outward: with this parametrisation the winding faces inward.
        if not inward:
            tris = tris[:, ::-1]
            nrm = nrm[:, ::-1]
        else:
            nrm = -nrm
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


def furnace_sphere(albedo=0.5, emission=0.5, resolution=(16, 16), radius=1.0):
    """Camera at the centre of a closed diffuse sphere that also emits: L = Le / (1 - albedo)."""
    mats = Materials.build([{"name": "shell", "diffuse": albedo, "emission": emission}])
    m = MeshBuilder()
    m.add_sphere((0, 0, 0), radius, 0, n_theta=32, n_phi=64, inward=True, smooth=False)
    cam = Camera.look_at((0, 0, 0), (0, 1, 0), lens_mm=20.0, resolution=resolution)
    return m.build(mats, camera=cam)


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


def kernel_radius_px(scene, radius):
    """``initial_radius_px`` that gives an orthographic camera the world-space gather ``radius``."""
    fx0, fx1, _, _ = scene.camera.frame
    return radius / ((fx1 - fx0) / scene.camera.resolution[0])


def disk_irradiance(intensity, distance, radius):
    """Irradiance from a point source at ``distance`` above a plane, averaged over a disk at its foot."""
    r2 = np.asarray(radius, np.float64) ** 2
    return 2.0 * intensity / r2 * (1.0 - distance / np.sqrt(distance ** 2 + r2))


def sun_through_slab(ior=1.5, irradiance=10.0, albedo=0.5, resolution=(8, 8)):
    """A sun at normal incidence through a glass slab onto a diffuse floor, camera under the slab.

    With ``max_bounces=2`` (photons cross the two faces and land, no internal reflection):
    E_floor = E (1 - F0)^2, F0 = ((ior - 1)/(ior + 1))^2, and L = albedo E_floor / pi.
    """
    mats = Materials.build([{"name": "floor", "diffuse": albedo},
                            {"name": "glass", "dielectric": 1.0, "ior": ior}])
    m = MeshBuilder()
    m.add_quad((-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0), 0)
    m.add_box((-0.3, -0.3, 1.0), (0.3, 0.3, 1.1), 1)
    lights = Lights.build([{"kind": "sun", "direction": (0, 0, -1), "power": irradiance}])
    cam = Camera(world_from_camera=_look_down(0.5), projection="orthographic",
                 frame=(-0.1, 0.1, -0.1, 0.1), resolution=resolution)
    return m.build(mats, lights, cam)


def camera_in_glass(ior=1.5, emission=1.0, resolution=(16, 16)):
    """An orthographic camera inside a glass cube looks at an emitter outside a face.

    Radiance leaving glass gains eta^2: L = eta^2 (1 - F0) Le sum_k F0^(2k) (internal round
    trips, each two more delta bounces; the back face shows a black world).
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


def glass_ceiling_room(resolution=(64, 48), pane=0.25):
    """A closed room lit only through a glass pane in its ceiling (the paper's scene 1)."""
    mats = Materials.build([
        {"name": "wall", "diffuse": (0.7, 0.7, 0.7)},
        {"name": "floor", "diffuse": (0.6, 0.5, 0.4)},
        {"name": "glass", "dielectric": (1, 1, 1), "ior": 1.5},
        {"name": "box", "diffuse": (0.3, 0.4, 0.7)},
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
    lights = Lights.build([{"kind": "area", "position": (0, 0, 3.6), "direction": (0, 0, -1),
                            "size": (1.0, 1.0), "power": 400.0}])
    cam = Camera.look_at((-1.8, -1.8, 1.2), (0.5, 0.5, 0.6), lens_mm=18.0, resolution=resolution)
    return m.build(mats, lights, cam)


BUILTIN = {"cornell_box": cornell_box, "furnace_sphere": furnace_sphere,
           "point_in_sphere": point_in_sphere, "spot_over_plane": spot_over_plane,
           "sun_through_slab": sun_through_slab, "camera_in_glass": camera_in_glass,
           "glass_ceiling_room": glass_ceiling_room}
