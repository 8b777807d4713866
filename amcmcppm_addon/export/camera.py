"""The render camera -> ``core.Camera``.

The image-plane window comes from ``Camera.view_frame(scene=...)`` (sensor fit,
aspect ratio, pixel aspect and shift included), normalised to z = -1 for
perspective cameras.  Object scale is removed from the camera matrix, as Cycles
does.  Depth of field follows Cycles (``intern/cycles/blender/camera.cpp``):
aperture radius = lens / (2 f-stop) (1 / (2 f-stop) for orthographic), focus
distance = ``dof.focus_distance`` or the distance of the focus object along
the view axis, and the aperture's Blades, Rotation and Ratio (polygonal and
anamorphic bokeh).  Panoramic cameras map their type and settings to the core's
panoramas (equirectangular, the two fisheyes, mirror ball); the equisolid
fisheye's sensor is fitted to the image as Blender fits it (``sensor_fit``).
Cycles' other panorama types and a panoramic camera's depth of field are
noted; those render as an equirectangular view, this one without depth of field.
A view of Stereoscopy (``CameraView``) moves the camera to its eye and shifts the window
by the eye's shift, both as Blender's RenderEngine gives them to Cycles.
The pixel filter is Cycles' Film > Pixel Filter (``scene.cycles``: type and width), which
the engine's Film panel edits; without the Cycles add-on, Blender's default
(Blackman-Harris, 1.5 pixels).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...core.scene import Camera, SceneError


def render_resolution(render):
    """(width, height) in pixels after the resolution percentage, as Blender computes it."""
    pct = render.resolution_percentage
    return max(1, render.resolution_x * pct // 100), max(1, render.resolution_y * pct // 100)


def render_border(render):
    """(x_min, x_max, y_min, y_max) of the border render, y from the bottom; the full frame if off."""
    if not render.use_border:
        return (0.0, 1.0, 0.0, 1.0)
    return (render.border_min_x, render.border_max_x, render.border_min_y, render.border_max_y)


def rendered_pixels(render) -> int:
    """Pixels the engine renders for these render settings: the border window if on."""
    x0, x1, y0, y1 = Camera(resolution=render_resolution(render), border=render_border(render)).window
    return (x1 - x0) * (y1 - y0)


PIXEL_FILTERS = {"BOX": "box", "GAUSSIAN": "gaussian", "BLACKMAN_HARRIS": "blackman_harris"}


def pixel_filter(scene):
    """{"pixel_filter", "filter_width"} of ``core.Camera`` from Cycles' Pixel Filter settings of
    ``scene`` (Blender's defaults without the Cycles add-on); a box is one pixel wide whatever the
    width (Cycles' sync ignores it there, and its panel hides it)."""
    cycles = getattr(scene, "cycles", None)
    kind = PIXEL_FILTERS.get(getattr(cycles, "pixel_filter_type", "BLACKMAN_HARRIS"), "blackman_harris")
    width = 1.0 if kind == "box" else float(getattr(cycles, "filter_width", 1.5))
    return {"pixel_filter": kind, "filter_width": min(max(width, 0.01), 10.0)}


def clip_range(ob, cam, log=None) -> dict:
    """{"clip_start", "clip_end"} of ``core.Camera`` for camera object ``ob`` (data ``cam``). Where
    Clip End is not beyond Clip Start (Blender lets both be 1e-6, or the end be the nearer) camera
    rays meet nothing and Cycles shows the world alone: so does the end a millionth beyond the
    start, named in a warning."""
    start, end = max(float(cam.clip_start), 0.0), float(cam.clip_end)
    if not end > start:
        if log is not None:
            log.warning(f"camera '{ob.name}': Clip End ({end:g} m) is not beyond Clip Start ({start:g} "
                        "m), so the camera sees nothing but the world")
        end = start * (1.0 + 1e-6) + 1e-9
    return {"clip_start": start, "clip_end": end}


@dataclass(frozen=True)
class CameraView:
    """One view of Stereoscopy as Blender's RenderEngine gives it (``camera_model_matrix`` and
    ``camera_shift_x`` after ``active_view_set``): the eye's camera matrix (world from camera,
    4 x 4) and its Shift X (the camera's own plus the eye's off-axis shift, in units of the
    sensor's fitted side, as ``Camera.shift_x``)."""
    name: str
    world_from_camera: np.ndarray
    shift_x: float


def export_camera(depsgraph, camera_object=None, resolution=None, border=None, log=None,
                  view=None) -> Camera:
    """``core.Camera`` for ``camera_object`` (default: the scene camera) seen from ``depsgraph``.

    resolution : (width, height) in pixels, percentage applied; default from the scene.
    border : (x_min, x_max, y_min, y_max), y from the bottom; default from the scene.
    view : a ``CameraView`` of Stereoscopy (a camera object's eye), or None for the camera itself.
    """
    scene = depsgraph.scene_eval
    render = scene.render
    ob = camera_object or scene.camera
    if ob is None:
        raise SceneError("the scene has no camera")
    ob = ob.evaluated_get(depsgraph)
    cam = ob.data
    resolution = tuple(int(v) for v in (resolution or render_resolution(render)))
    border = tuple(float(v) for v in (border or render_border(render)))

    view = view if ob.type == "CAMERA" else None       # (Blender's eyes are a camera object's)
    matrix = ob.matrix_world if view is None else view.world_from_camera
    world_from_camera, zero_axes = _without_scale(np.array(matrix, np.float64))
    if zero_axes:
        # Cycles normalises the columns too (to NaN there): its camera rays meet nothing.
        if log is not None:
            log.warning(f"camera '{ob.name}' has zero scale along its local {zero_axes}, so it sees nothing "
                        "but the world (as in Cycles)")
        clip = {"clip_start": 1.0, "clip_end": 1.0 + 1e-6}
    elif ob.type != "CAMERA":
        clip = {"clip_start": 1e-5, "clip_end": 1e5}
    else:
        clip = clip_range(ob, cam, log)
    if ob.type != "CAMERA":
        return _through_object(ob, render, world_from_camera, resolution, border, clip, log,
                               pixel_filter(scene))
    if cam.type == "PANO":
        return replace(_panorama(ob, cam, world_from_camera, resolution, border, clip, log),
                       **pixel_filter(scene))
    corners = np.array([tuple(v) for v in cam.view_frame(scene=scene)], np.float64)   # (4, 3)
    projection = "orthographic" if cam.type == "ORTHO" else "perspective"
    if projection == "perspective":
        xy = corners[:, :2] / -corners[:, 2:3]
    else:
        xy = corners[:, :2]
    frame = (xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max())
    if view is not None and view.shift_x != cam.shift_x:
        frame = _shifted(frame, view.shift_x - float(cam.shift_x), cam.sensor_fit)

    aperture_radius, focus_distance, shape = 0.0, 10.0, {}
    dof = cam.dof
    if dof.use_dof:
        fstop = max(float(dof.aperture_fstop), 1e-5)
        aperture_radius = 1.0 / (2.0 * fstop) if projection == "orthographic" \
            else cam.lens * 1e-3 / (2.0 * fstop)
        focus_distance = _focus_distance(depsgraph, dof, world_from_camera)
        if focus_distance <= 0:
            focus_distance = 1e-3
        shape = {"aperture_blades": int(dof.aperture_blades),
                 "aperture_rotation": float(dof.aperture_rotation),
                 "aperture_ratio": max(float(dof.aperture_ratio), 1e-3)}
    return Camera(world_from_camera=world_from_camera, projection=projection,
                  frame=tuple(float(v) for v in frame), resolution=resolution, border=border,
                  aperture_radius=float(aperture_radius), focus_distance=float(focus_distance), **shape,
                  **clip, **pixel_filter(scene))


# What Cycles makes of an active camera that is not a camera object (``blender_camera_init``, its
# ``blender_camera_from_object``; checked against Cycles in bpy 5.0.1): a perspective view through
# a 50 mm lens on a 36 mm sensor fitted to the image's longer side, clipped at 1e-5 and 1e5 m; a
# light's lens is 16 mm / tan(spot size / 2) (a light that is not a spot keeps Blender's default
# spot size, 45 degrees, which its data do not show).
DEFAULT_LENS = 50.0
DEFAULT_SENSOR = 36.0
DEFAULT_SPOT_SIZE = np.radians(45.0)


def _through_object(ob, render, world_from_camera, resolution, border, clip, log, film):
    """``core.Camera`` of an active camera ``ob`` that is not a camera object (an empty, a mesh, a
    light: Blender lets any object be the scene's camera), as Cycles renders it."""
    lens = DEFAULT_LENS
    if ob.type == "LIGHT":
        size = float(getattr(ob.data, "spot_size", DEFAULT_SPOT_SIZE))
        if 0.0 < size < np.pi:
            lens = 16.0 / np.tan(0.5 * size)
    if log is not None:
        log.warning(f"the active camera '{ob.name}' is not a camera object: rendering its view as Cycles "
                    f"does, through a {lens:.3g} mm lens on a 36 mm sensor")
    x = float(render.resolution_x) * float(render.pixel_aspect_x)
    y = float(render.resolution_y) * float(render.pixel_aspect_y)
    half = 0.5 * DEFAULT_SENSOR / lens
    hx, hy = (half, half * y / x) if x >= y else (half * x / y, half)
    return Camera(world_from_camera=world_from_camera, projection="perspective", frame=(-hx, hx, -hy, hy),
                  resolution=resolution, border=border, **clip, **film)


def _without_scale(matrix):
    """(matrix with its 3 x 3 part's columns made unit, its columns of zero length named: "" or e.g.
    "X axis", "X and Z axes").  With such columns the 3 x 3 part becomes the rotation nearest to it (the
    orthogonal factor of its polar decomposition, any where it is all zero): finite whatever."""
    norms = np.linalg.norm(matrix[:3, :3], axis=0)
    zero = norms < 1e-12
    if not zero.any():
        matrix[:3, :3] /= norms
        return matrix, ""
    u, _, vt = np.linalg.svd(matrix[:3, :3])
    if np.linalg.det(u @ vt) < 0:
        u[:, -1] = -u[:, -1]
    matrix[:3, :3] = u @ vt
    names = ["XYZ"[k] for k in np.flatnonzero(zero)]
    if len(names) == 1:
        return matrix, f"{names[0]} axis"
    return matrix, f"{', '.join(names[:-1])} and {names[-1]} axes"


PANORAMA_TYPES = {"EQUIRECTANGULAR": "equirectangular", "FISHEYE_EQUIDISTANT": "fisheye_equidistant",
                  "FISHEYE_EQUISOLID": "fisheye_equisolid", "MIRRORBALL": "mirrorball"}


def _panorama(ob, cam, world_from_camera, resolution, border, clip, log):
    """``core.Camera`` of a panoramic camera (Cycles' projections, ``core.camera``)."""
    notes = []
    projection = PANORAMA_TYPES.get(cam.panorama_type)
    if projection is None:
        notes.append(f"the {cam.panorama_type.lower().replace('_', ' ')} panorama is not supported; "
                     "rendering an equirectangular one")
        projection = "equirectangular"
    if cam.dof.use_dof:
        notes.append("depth of field is not supported on panoramic cameras (rendered sharp)")
    if notes and log is not None:
        log.warning(f"camera '{ob.name}': " + "; ".join(notes))
    w, h = resolution
    sw, sh = float(cam.sensor_width), float(cam.sensor_height)
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if w >= h else "AUTO_VERTICAL"
    # Blender fits the sensor's width (AUTO: along the longer side) or height to the image.
    sensor = {"HORIZONTAL": (sw, sw * h / w), "AUTO_VERTICAL": (sw * w / h, sw),
              "VERTICAL": (sh * w / h, sh)}[fit]
    return Camera(world_from_camera=world_from_camera, projection=projection, resolution=resolution,
                  border=border, **clip,
                  latitude_range=(float(cam.latitude_min), float(cam.latitude_max)),
                  longitude_range=(float(cam.longitude_min), float(cam.longitude_max)),
                  fisheye_fov=float(cam.fisheye_fov), fisheye_lens=float(cam.fisheye_lens),
                  sensor_size=sensor)


def _shifted(frame, shift, sensor_fit):
    """``frame`` (x_min, x_max, y_min, y_max) moved by ``shift`` more Shift X: Blender's shift is in
    units of the side the sensor fits (AUTO: the longer one), a shift of 1 a whole frame width
    with a horizontal fit."""
    width, height = frame[1] - frame[0], frame[3] - frame[2]
    side = {"HORIZONTAL": width, "VERTICAL": height}.get(sensor_fit, max(width, height))
    return (frame[0] + shift * side, frame[1] + shift * side, frame[2], frame[3])


def _focus_distance(depsgraph, dof, world_from_camera):
    target = dof.focus_object
    if target is None:
        return float(dof.focus_distance)
    target = target.evaluated_get(depsgraph)
    view_dir = world_from_camera[:3, 2]
    offset = world_from_camera[:3, 3] - np.array(target.matrix_world.translation, np.float64)
    return float(abs(view_dir @ offset))
