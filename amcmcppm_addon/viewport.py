"""The 3D viewport's Rendered shading: a live render of the view, started over on every change.

``AMCMCPPMRenderEngine.view_update`` (the depsgraph changed) and ``view_draw`` (a redraw) hand
their calls to one :class:`ViewportRender` per engine.  It exports the scene when the depsgraph
changed, takes the camera from the view's matrices (``core.Camera.from_view``: the viewport's
own view, or the camera's with its zoom and offset when looking through it), and runs the
render in a process of its own (``core.live.LiveRender``: one worker, the scene's settings but
``viewport_passes`` passes at ``viewport_pixel_size``, the first of ``VIEWPORT_FIRST_PHOTONS``
photons unless First Pass Photons says otherwise; a large view first shows a coarse preview,
``core.live.PREVIEW_PIXELS``), so that Blender's interface never waits for it.
A moved view sends only its camera: the server renders the scene it holds through it, with the
acceleration structure it built (``LiveRender.start``); a change of the depsgraph is exported again
and starts the render over only if the export differs (a selection does not), and the server keeps
its BVH through edits that leave the triangles as they were (``core/live.py``).  Each redraw
shows the newest pass, scaled to the region, through Blender's display transform, and asks for
another redraw while the render goes on.

Only ``draw`` touches the GPU (``gpu`` exists only with a window: ``shared/docs/blender.md`` 4);
:meth:`ViewportRender.refresh` holds the rest and runs headless (``tests/addon/test_viewport.py``).
"""
from __future__ import annotations

import dataclasses
import traceback

import numpy as np

from ..core import SceneError
from ..core.live import LiveRender
from ..core.scene import Camera
from ..core.settings import VIEWPORT_FIRST_PHOTONS
from .export import export_scene, render_settings_from
from .export.camera import pixel_filter


class ViewportRender:
    """One viewport's live render (see the module docstring)."""

    def __init__(self):
        self.live = None
        self.exported = None        # the exported scene
        self.stale = True           # whether the depsgraph changed since
        self.key = None             # what the running render shows: view, projection, size, settings
        self.passes = 0             # ... of which its passes
        self.image = None           # the newest image (h, w, 4), top row first
        self.stats = None           # ... and its statistics (pass, elapsed_s, photons)
        self.message = ""           # an error to show instead of statistics
        self._texture = None

    def scene_changed(self):
        """The depsgraph changed: export again at the next refresh (and start over if the scene
        differs: selecting an object changes the depsgraph, not the scene)."""
        self.stale = True

    def refresh(self, depsgraph, view_matrix, window_matrix, perspective, region_size) -> bool:
        """Start the render over if the scene, its settings or the view changed since, then take
        its newest image; True when there is a new one (``self.image``)."""
        props = depsgraph.scene_eval.amcmcppm
        pixel = int(props.viewport_pixel_size)
        size = (max(1, int(region_size[0]) // pixel), max(1, int(region_size[1]) // pixel))
        view, window = np.array(view_matrix, np.float64), np.array(window_matrix, np.float64)
        passes = int(props.viewport_passes)
        first = props.first_pass_photons or VIEWPORT_FIRST_PHOTONS
        settings = render_settings_from(props, passes=passes, time_limit=0.0, workers=1,
                                        first_pass_photons=first)
        key = (view.tobytes(), window.tobytes(), bool(perspective), size, settings)
        if self.stale or key != self.key:
            camera = Camera.from_view(view, window, perspective, size, **pixel_filter(depsgraph.scene_eval))
            new_scene = self.stale and self._export(depsgraph, camera)
            if not new_scene and key == self.key:
                return self._take()
            self.key, self.passes = key, passes
            self.message = ""
            self.stats = None           # (the last image stays on screen until the new one comes)
            # (only the view moved: the export stands, and the live render keeps its scene and
            # BVH; a world made with the camera's view, a backplate, keeps the view it was
            # exported with)
            scene = self.exported.scene
            if not new_scene:
                scene = dataclasses.replace(scene, camera=camera)
            if self.exported.is_empty:
                self.close()
                self.image, self.stats = np.zeros((size[1], size[0], 4), np.float32), None
                self.message = "nothing to render (no geometry, no lights and a black world)"
                return True
            if self.live is None:
                self.live = LiveRender()
            self.live.start(scene, settings)
        return self._take()

    def _export(self, depsgraph, camera) -> bool:
        """Export the scene through ``camera``; whether it differs from the last export (its camera
        aside), which it then replaces."""
        exported = export_scene(depsgraph, camera=camera)
        self.stale = False
        if self.exported is not None and same_scene(exported.scene, self.exported.scene):
            return False
        self.exported = exported
        return True

    def _take(self) -> bool:
        """Take the live render's newest image, if there is a new one."""
        if self.live is None:
            return False
        got = self.live.latest()
        if got is None:
            return False
        self.image, self.stats = got
        return True

    @property
    def running(self) -> bool:
        return self.live is not None and self.live.running

    def status(self) -> str:
        """The line the viewport shows in its corner."""
        if self.message:
            return f"AMCMCPPM: {self.message}"
        if self.stats is None:
            return "Rendering the first pass"
        if self.stats.get("preview"):
            return f"Preview, rendering the first pass, {self.stats['elapsed_s']:.1f} s"
        passes = self.stats["pass"]
        done = "" if self.running else ", done"
        return f"Pass {passes} / {self.passes}, {self.stats['elapsed_s']:.1f} s{done}"

    def draw(self, engine, context, depsgraph):
        """``view_draw``: refresh, then draw the newest image over the region."""
        import gpu
        from gpu_extras.presets import draw_texture_2d

        region, view = context.region, context.region_data
        try:
            if self.refresh(depsgraph, view.view_matrix, view.window_matrix, view.is_perspective,
                            (region.width, region.height)) or self._texture is None:
                self._texture = None
                if self.image is not None:
                    h, w = self.image.shape[:2]
                    pixels = np.ascontiguousarray(self.image[::-1], np.float32).ravel()   # bottom row first
                    self._texture = gpu.types.GPUTexture(
                        (w, h), format='RGBA16F', data=gpu.types.Buffer('FLOAT', pixels.size, pixels))
        except (SceneError, RuntimeError, ValueError) as exc:
            self.fail(exc)
        if self._texture is not None:
            gpu.state.blend_set('ALPHA_PREMULT')
            engine.bind_display_space_shader(depsgraph.scene_eval)
            draw_texture_2d(self._texture, (0, 0), region.width, region.height)
            engine.unbind_display_space_shader()
            gpu.state.blend_set('NONE')
        engine.update_stats("", self.status())
        if self.running:
            engine.tag_redraw()

    def fail(self, exc):
        """Show ``exc`` in the viewport and stop rendering (until the next change)."""
        self.close()
        first = str(exc).strip().splitlines()
        self.message = f"viewport render failed: {first[-1] if first else type(exc).__name__}"
        traceback.print_exception(exc)

    def close(self):
        if self.live is not None:
            self.live.close()
            self.live = None


def same_scene(a, b) -> bool:
    """Whether core scenes ``a`` and ``b`` hold the same data (``Scene.to_arrays``), their cameras
    aside."""
    x, y = a.to_arrays(), b.to_arrays()
    keys = {k for k in x if not k.startswith("camera.")}
    if keys != {k for k in y if not k.startswith("camera.")}:
        return False
    for k in keys:
        u, v = np.asarray(x[k]), np.asarray(y[k])
        if u.shape != v.shape or u.dtype != v.dtype or not np.array_equal(u, v):
            return False
    return True
