"""Camera rays for the pixels of the render window."""
from __future__ import annotations

import numpy as np

from . import sampling as smp
from .scene import PANORAMAS

# Panoramic cameras' footprints come from the directions of points this many pixels apart.
FOOTPRINT_STEP = 1e-3
# Points of the pixel filters' inverted distributions (Cycles' FILTER_TABLE_SIZE is 1024).
FILTER_TABLE_SIZE = 4096


def filter_offsets(kind, width, u):
    """(n,) offsets in pixels from a pixel's centre along one axis for uniform numbers ``u`` (n,),
    distributed by the pixel filter ``kind`` (``Camera.pixel_filter``) of ``width``, as Cycles'
    ``filter_table`` (scene/film.cpp) inverts it: a box is uniform over the width; a Gaussian
    exp(-2 (6 x / w)^2) over +-3 w / 2 with w = 3 ``width`` (sigma = ``width`` / 4); Blackman-Harris
    over +-``width`` (its window twice the width).  Both halves are the same distribution mirrored,
    and ``u`` = 0.5 is the centre."""
    u = np.asarray(u, np.float64)
    if kind == "box":
        return (u - 0.5) * width
    if kind == "gaussian":
        w = 3.0 * width
        def f(x):
            v = x * 6.0 / w
            return np.exp(-2.0 * v * v)
    elif kind == "blackman_harris":
        w = 2.0 * width
        def f(x):
            v = 2.0 * np.pi * (x / w + 0.5)
            return 0.35875 - 0.48829 * np.cos(v) + 0.14128 * np.cos(2.0 * v) - 0.01168 * np.cos(3.0 * v)
    else:
        raise ValueError(f"unknown pixel filter {kind!r}")
    # The half axis [0, w / 2]: its CDF by the trapezoid rule, inverted by interpolation.
    x = np.linspace(0.0, 0.5 * w, FILTER_TABLE_SIZE)
    fx = np.abs(f(x))
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (fx[1:] + fx[:-1]))])
    cdf /= cdf[-1]
    s = 2.0 * u - 1.0
    return np.sign(s) * np.interp(np.abs(s), cdf, x)


def stratified_jitter(salt, pass_index, pixel_ids):
    """(n, 2) pixel-jitter numbers in [0, 1) for ``pixel_ids`` (n,) in pass ``pass_index``
    (``RenderSettings.pixel_jitter``): point ``pass_index`` of the (0, 2)-sequence in base 2
    (:func:`~core.sampling.sobol_02`), its bits XORed with each pixel's own 32 random bits
    (:func:`~core.sampling.hash_bits` of its id and ``salt``; a random digital shift).  So every
    pass's jitter is uniform in every pixel, as independent numbers are, while a pixel's passes
    spread over it evenly instead of clumping (its first 2^k passes one in each of 2^k strata of
    every shape): the noise of where the passes look in their pixels (edges, textures, small bright
    spots, the light samples' sharp shadows) falls nearly as 1 / passes, not 1 / sqrt(passes)."""
    return _shifted(salt, pixel_ids, smp.sobol_02(int(pass_index)))


def _shifted(salt, pixel_ids, point):
    """(n, len(point)) numbers in [0, 1): the 32-bit coordinates ``point`` XORed with random bits
    of each pixel's own (:func:`~core.sampling.hash_bits` of ``pixel_ids`` and ``salt``)."""
    shift = smp.hash_bits(pixel_ids, salt, len(point)) >> np.uint64(32)
    return (shift ^ np.array(point, np.uint64)).astype(np.float64) * 2.0 ** -32


def stratified_lens(salt, pass_index, pixel_ids):
    """(n, 2) lens-sample numbers in [0, 1) for ``pixel_ids`` (n,) in pass ``pass_index``, the lens's
    counterpart of :func:`stratified_jitter` (``RenderSettings.pixel_jitter``, a camera with depth
    of field): point ``pass_index`` of Sobol's dimensions 3 and 4 (:func:`~core.sampling.sobol`),
    its bits XORed with 64 random bits of the pixel's own.  With the jitter's dimensions 1 and 2 a
    pixel's passes follow the 4-dimensional Sobol sequence: its first 64 passes put one lens sample
    in each of 64 strips across either axis and, paired with their pixel points, one in each of the
    8 x 8 cells of every (pixel axis, lens axis) pair, so that the blur of what lies out of focus
    (a pixel's point and its lens sample both move where its ray lands) settles faster too.  Before
    stop 65 the lens samples were independent numbers; the jitter's own (0, 2)-sequence with its
    index Owen-scrambled per pixel stratifies the lens alone, pairs it with the pixel point at random
    and converges more slowly (README, "Pixel jitter stratified over passes")."""
    return _shifted(salt, pixel_ids, smp.sobol(int(pass_index), (3, 4)))


def stratified_choices(salt, pass_index, pixel_ids, depth=0):
    """(n, 3) numbers in [0, 1) for the lobe choice at surface ``depth`` (0 the first) of
    ``pixel_ids``' (n,) camera paths in pass ``pass_index`` (``RenderSettings.pixel_jitter``; the
    eye pass's ``u``: a non-delta lobe or which delta lobe, then the delta lobe's own two numbers,
    as reflection or refraction by a glass's Fresnel factor).  At the first surface point
    ``pass_index`` of Sobol's dimensions 5 to 7 (:func:`~core.sampling.sobol`), its bits XORed with
    96 random bits of the pixel's own, jointly stratified with where in the pixel and on the lens
    each pass looks.  At each surface after it (stop 66) the first three dimensions at the pass
    index, index and coordinates Owen-scrambled with seeds of the pixel's and the depth's own
    (:func:`~core.sampling.scrambled_sobol`, as :func:`~core.direct.stratified_light`): stratified over
    the passes, paired at random with the numbers before.  So a pixel whose ray meets glass, a
    mirror or a coat, at any depth, splits its passes between the lobes in their proportions
    instead of at random."""
    if depth == 0:
        return _shifted(salt, pixel_ids, smp.sobol(int(pass_index), (5, 6, 7)))
    salt = (salt + depth * 0x632BE59BD9B4E019) % (1 << 64)
    seeds = smp.hash_bits(pixel_ids, salt, 2).view(np.uint32)
    return smp.scrambled_sobol(np.full(len(pixel_ids), pass_index, np.uint64), (1, 2, 3), seeds)


def aperture_points(camera, u1, u2):
    """(x, y) (n,) points on ``camera``'s aperture in camera units, uniform over it, from uniform
    numbers ``u1``, ``u2`` (n,), as Cycles' ``camera_sample_aperture``: the disc of
    ``aperture_radius`` (Shirley and Chiu's concentric map), or with ``aperture_blades`` of 3 or
    more the regular polygon of that circumradius, a corner picked by ``u1`` and a point of its
    triangle (centre and two neighbouring corners, at +-pi / blades from the polygon's first
    axis, turned by ``aperture_rotation``); x then divided by ``aperture_ratio``."""
    blades = int(camera.aperture_blades)
    if blades < 3:
        x, y = smp.concentric_disk(u1, u2)
    else:
        corner = np.minimum(np.floor(u1 * blades), blades - 1)
        a = np.sqrt(u1 * blades - corner)       # (the corner's share of u1, reused)
        b = u2 * a
        a = 1.0 - a
        half = np.pi / blades
        px, py = (a + b) * np.cos(half), (a - b) * np.sin(half)
        turn = camera.aperture_rotation + corner * 2.0 * half
        c, s = np.cos(turn), np.sin(turn)
        x, y = c * px - s * py, s * px + c * py
    return camera.aperture_radius * x / camera.aperture_ratio, camera.aperture_radius * y


def generate_camera_rays(camera, pixel_ids, u):
    """One ray per pixel ``pixel_ids`` of ``camera.window`` (row-major from its top-left pixel).

    pixel_ids : (n,) int64; u : (n, 4) uniform numbers: pixel jitter x, y (by the camera's pixel
    filter, :func:`filter_offsets`) and lens sample x, y.
    Returns ``origins`` (n, 3) float64, ``directions`` (n, 3) float64 unit,
    ``tmax`` (n,) far-clip distances along the rays and ``footprint`` (n,): the
    width of one pixel at unit distance along the ray (perspective; panoramic: the square
    root of the pixel's solid angle) or the constant pixel width (orthographic).  A
    panoramic camera's pixels that see nothing (outside a fisheye's circle) get zero
    directions.
    """
    x0, x1, y0, y1 = camera.window
    w, h = camera.resolution
    row, col = np.divmod(pixel_ids, x1 - x0)
    if camera.pixel_filter == "box" and camera.filter_width == 1.0:
        px = (x0 + col) + u[:, 0]
        py = (y0 + row) + u[:, 1]
    else:
        # (Cycles' Pixel Filter: an offset from the pixel's centre, by the filter)
        px = (x0 + col + 0.5) + filter_offsets(camera.pixel_filter, camera.filter_width, u[:, 0])
        py = (y0 + row + 0.5) + filter_offsets(camera.pixel_filter, camera.filter_width, u[:, 1])
    fx0, fx1, fy0, fy1 = camera.frame
    # Image-plane coordinates: x grows to the right, y upward; rows are counted from the top.
    x = fx0 + (fx1 - fx0) * px / w
    y = fy1 - (fy1 - fy0) * py / h
    n = len(px)
    m = camera.world_from_camera
    rot = m[:3, :3]
    pixel_width = (fx1 - fx0) / w
    if camera.projection in PANORAMAS:
        return _panorama_rays(camera, px / w, 1.0 - py / h)
    if camera.projection == "perspective":
        d_cam = np.stack([x, y, -np.ones(n)], axis=1)
        o_cam = None                            # the camera's centre (a pinhole)
        if camera.aperture_radius > 0:
            lx, ly = aperture_points(camera, u[:, 2], u[:, 3])
            lens = np.stack([lx, ly, np.zeros(n)], axis=1)
            focus = d_cam * camera.focus_distance
            o_cam = lens
            d_cam = focus - lens
        # Distances along -Z convert to distances along the ray by |d| / |d.z|.
        scale = smp.length(d_cam) / np.abs(d_cam[:, 2])
        # A pixel at the z = -1 plane, seen from distance |(x, y, -1)|.
        footprint = pixel_width / np.sqrt(x * x + y * y + 1.0)
    else:
        o_cam = np.stack([x, y, np.zeros(n)], axis=1)
        d_cam = np.tile([0.0, 0.0, -1.0], (n, 1))
        if camera.aperture_radius > 0:
            lx, ly = aperture_points(camera, u[:, 2], u[:, 3])
            lens = np.stack([lx, ly, np.zeros(n)], axis=1)
            focus = o_cam + d_cam * camera.focus_distance
            o_cam = o_cam + lens
            d_cam = focus - o_cam
        scale = smp.length(d_cam) / np.abs(d_cam[:, 2])
        footprint = np.full(n, pixel_width)
    origins = m[:3, 3] if o_cam is None else o_cam @ rot.T + m[:3, 3]
    dirs = smp.normalize(d_cam @ rot.T)
    # Camera matrices may carry a scale: clip distances are measured in world units along -Z.
    axis_scale = np.linalg.norm(rot[:, 2])
    origins = origins + dirs * (camera.clip_start * scale * axis_scale)[:, None]
    tmax = np.maximum((camera.clip_end - camera.clip_start) * scale * axis_scale, 0.0)
    return origins, dirs, tmax, footprint * axis_scale


def _panorama_rays(camera, u, v):
    """``generate_camera_rays`` for a panoramic camera at image points ``u``, ``v`` in [0, 1]
    (v from the bottom)."""
    w, h = camera.resolution
    m = camera.world_from_camera
    rot = m[:3, :3]
    d_cam, ok = panorama_directions(camera, u, v)
    # The pixel's solid angle |d_u x d_v| du dv from the directions a small step away.
    step = FOOTPRINT_STEP
    d_u, ok_u = panorama_directions(camera, u + step / w, v)
    d_v, ok_v = panorama_directions(camera, u, v + step / h)
    footprint = np.sqrt(smp.length(np.cross(d_u - d_cam, d_v - d_cam))) / step
    # A pixel on the rim of a fisheye's circle: its neighbour a step away may see nothing.
    rim = ok & ~(ok_u & ok_v)
    if rim.any():
        inner = ok & ~rim
        footprint[rim] = np.median(footprint[inner]) if inner.any() else 1.0 / max(w, h)
    axis_scale = np.linalg.norm(rot[:, 2])
    dirs = d_cam @ rot.T
    dirs[ok] = smp.normalize(dirs[ok])
    origins = m[:3, 3] + dirs * (camera.clip_start * axis_scale)
    tmax = np.where(ok, max((camera.clip_end - camera.clip_start) * axis_scale, 0.0), 0.0)
    return origins, dirs, tmax, np.where(ok, footprint, 0.0) * axis_scale


def panorama_directions(camera, u, v):
    """(n, 3) camera-space unit directions (-Z ahead, +Y up) seen at image points ``u``, ``v``
    in [0, 1] (v from the bottom) by a panoramic camera, and (n,) whether each sees anything
    (directions are zero where not).  Cycles' projections (``kernel/camera/projection.h``) in
    Blender's camera frame, checked pixel by pixel against Cycles 5.0 in
    ``tests/addon/test_addon_export.py``."""
    n = len(u)
    ok = np.ones(n, bool)
    kind = camera.projection
    if kind == "equirectangular":
        (lat0, lat1), (lon0, lon1) = camera.latitude_range, camera.longitude_range
        lon = lon0 + (lon1 - lon0) * u              # 0 ahead, growing to the right
        lat = lat0 + (lat1 - lat0) * v
        c = np.cos(lat)
        d = np.stack([c * np.sin(lon), np.sin(lat), -c * np.cos(lon)], axis=1)
    elif kind == "mirrorball":
        x, y = 2.0 * u - 1.0, 2.0 * v - 1.0
        r2 = x * x + y * y
        ok = r2 <= 1.0
        z = np.sqrt(np.maximum(1.0 - r2, 0.0))      # the ball's normal (x, y, z)
        # Cycles' reflection about it, which sees straight ahead at the centre.
        d = np.stack([2.0 * z * x, 2.0 * z * y, 1.0 - 2.0 * z * z], axis=1)
    else:
        if kind == "fisheye_equidistant":
            x, y = 2.0 * u - 1.0, 2.0 * v - 1.0
            r = np.hypot(x, y)
            ok = r <= 1.0
            theta = r * camera.fisheye_fov / 2.0
        else:
            width, height = camera.sensor_size
            x, y = (u - 0.5) * width, (v - 0.5) * height
            r = np.hypot(x, y)
            lens = camera.fisheye_lens
            ok = r <= 2.0 * lens * np.sin(camera.fisheye_fov / 4.0)
            theta = 2.0 * np.arcsin(np.clip(r / (2.0 * lens), 0.0, 1.0))
        safe = np.where(r > 0, r, 1.0)
        s = np.sin(theta)
        d = np.stack([s * x / safe, s * y / safe, -np.cos(theta)], axis=1)
    d[~ok] = 0.0
    return d, ok
