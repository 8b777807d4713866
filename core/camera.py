"""Camera rays for the pixels of the render window."""
from __future__ import annotations

import numpy as np

from . import sampling as smp


def generate_camera_rays(camera, pixel_ids, u):
    """One ray per pixel ``pixel_ids`` of ``camera.window`` (row-major from its top-left pixel).

    pixel_ids : (n,) int64; u : (n, 4) uniform numbers: pixel jitter x, y and lens sample x, y.
    Returns ``origins`` (n, 3) float64, ``directions`` (n, 3) float64 unit,
    ``tmax`` (n,) far-clip distances along the rays and ``footprint`` (n,): the
    width of one pixel at unit distance along the ray (perspective) or the
    constant pixel width (orthographic).
    """
    x0, x1, y0, y1 = camera.window
    w, h = camera.resolution
    row, col = np.divmod(pixel_ids, x1 - x0)
    px = (x0 + col) + u[:, 0]
    py = (y0 + row) + u[:, 1]
    fx0, fx1, fy0, fy1 = camera.frame
    # Image-plane coordinates: x grows to the right, y upward; rows are counted from the top.
    x = fx0 + (fx1 - fx0) * px / w
    y = fy1 - (fy1 - fy0) * py / h
    n = len(px)
    m = camera.world_from_camera
    rot = m[:3, :3]
    pixel_width = (fx1 - fx0) / w
    if camera.projection == "perspective":
        d_cam = np.stack([x, y, -np.ones(n)], axis=1)
        o_cam = np.zeros((n, 3))
        if camera.aperture_radius > 0:
            lx, ly = smp.concentric_disk(u[:, 2], u[:, 3])
            lens = camera.aperture_radius * np.stack([lx, ly, np.zeros(n)], axis=1)
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
            lx, ly = smp.concentric_disk(u[:, 2], u[:, 3])
            lens = camera.aperture_radius * np.stack([lx, ly, np.zeros(n)], axis=1)
            focus = o_cam + d_cam * camera.focus_distance
            o_cam = o_cam + lens
            d_cam = focus - o_cam
        scale = smp.length(d_cam) / np.abs(d_cam[:, 2])
        footprint = np.full(n, pixel_width)
    origins = o_cam @ rot.T + m[:3, 3]
    dirs = smp.normalize(d_cam @ rot.T)
    # Camera matrices may carry a scale: clip distances are measured in world units along -Z.
    axis_scale = np.linalg.norm(rot[:, 2])
    origins = origins + dirs * (camera.clip_start * scale * axis_scale)[:, None]
    tmax = np.maximum((camera.clip_end - camera.clip_start) * scale * axis_scale, 0.0)
    return origins, dirs, tmax, footprint * axis_scale
