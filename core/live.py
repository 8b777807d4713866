"""A render that runs in a process of its own and starts over when its scene or view changes.

This is what Blender's 3D viewport shows in Rendered shading (``amcmcppm_addon/viewport.py``):
the viewport asks for a new render whenever the user moves the view or edits the scene, and
must never wait for one.  :class:`LiveRender` keeps one server process (:func:`serve`, started
with :func:`core.parallel.start_process`) and sends it jobs: a scene file, a camera and settings.
A job whose scene differs from the last one's only by its camera (the view moved) names the last
one's file, and the server, which keeps that scene and its ``RenderContext``, renders it through
the new camera (``RenderContext.with_camera``) without loading it or building its BVH again.  An
edited scene is sent again, and its BVH kept if the edit left the triangles as they were (a
material's or a light's, unless the light moves the scene's bounds far: ``Accel``'s ``reuse``);
an edit that moved a few of them (an object dragged) keeps it too, with embree's scenes of those
and of what lies about their old places built apart (``core.accel.SplitScene``).  The
server renders the newest job with :func:`core.render` in that process (one worker, no pool to
start), writes the image after every pass into the job's folder (a file replaced atomically; a
large image's job first a coarse preview, ``PREVIEW_PIXELS``), and leaves a job as soon as a
newer one supersedes it (a stop file, polled between photon batches, as the photon workers poll
theirs, and between the steps of preparing a pass) or the process that sent it is gone.  Nothing
here runs in the caller's process but file reads: the viewport's Python thread never holds a
render, and the GIL is not shared with one.
"""
from __future__ import annotations

import dataclasses
import json
import os
import pickle
import re
import shutil
import subprocess
import sys
import tempfile
import traceback

import numpy as np

from .parallel import _send, start_process

# Seconds the server gets to leave after it is told to stop, before it is killed.
STOP_GRACE_S = 2.0
# A job whose image has more pixels than this first renders a preview, published as pass 0: one
# pass of uniform photons with the image's sides halved until it has at most this many (a first
# pass of 1280 x 720 costs 2 s on the Cornell box, one of 320 x 180 a fifth of that), so that a
# large viewport shows something soon, as Cycles' viewport starts coarse (Start Pixels).
PREVIEW_PIXELS = 256 * 256
# The files of a job in the folder (job_file): its scene, newest image and statistics, its error,
# and the flags that it is done or superseded.
JOB_FILES = {"scene": ".npz", "image": ".npy", "stats": ".json", "error": ".txt", "done": ".flag",
             "stop": ".flag"}


def job_file(folder, kind, job):
    """The path of job ``job``'s file of ``kind`` (``JOB_FILES``), for the client and the server."""
    return os.path.join(folder, f"{kind}{job}{JOB_FILES[kind]}")


class LiveRender:
    """The client: ``start`` a job, read its ``latest`` image, ``close``."""

    def __init__(self):
        shm = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
        self.folder = tempfile.mkdtemp(prefix="amcmcppm-live-", dir=shm)
        self.proc = None
        self.job = 0
        self._shown = None          # (job, pass) of the last image returned by latest()
        self._scene = None          # the scene last written, and its file
        self._scene_path = None

    def start(self, scene, settings):
        """Render ``scene`` (``core.Scene``) with ``settings`` (``RenderSettings``; one worker is
        used whatever they say) from now on, leaving the job before it.  A scene that shares every
        field but its camera with the last one (``dataclasses.replace(scene, camera=...)``) is not
        written again: the server keeps that one (arrays changed in place are not seen)."""
        if self.job:
            open(job_file(self.folder, "stop", self.job), "w").close()
        self.job += 1
        if not _same_but_camera(scene, self._scene):
            self._scene_path = job_file(self.folder, "scene", self.job)
            # (uncompressed, unlike Scene.save: the caller, the viewport's redraw, waits for it)
            np.savez(self._scene_path, **scene.to_arrays())
            self._scene = scene
        for name in os.listdir(self.folder):
            # The files of earlier jobs, but their stop files (the server skips a job still
            # queued in its pipe by its stop file) and the scene file in use.
            m = re.fullmatch(r"(scene|image|stats|error|done)(\d+)\.\w+", name)
            if m and int(m.group(2)) < self.job and os.path.join(self.folder, name) != self._scene_path:
                try:
                    os.remove(os.path.join(self.folder, name))
                except OSError:
                    pass
        if self.proc is None or self.proc.poll() is not None:
            self.proc = start_process("live.serve")
        fields = {f: getattr(settings, f) for f in settings.__dataclass_fields__}
        fields["workers"] = 1
        # (the camera's fields, not the object: Blender's add-on and the server name its class's
        # module differently)
        camera = {f.name: getattr(scene.camera, f.name) for f in dataclasses.fields(scene.camera)}
        _send(self.proc, ("render", self.job, self._scene_path, camera, fields, self.folder))

    def latest(self):
        """(image (h, w, 4) float32 linear RGBA, top row first; the job's statistics: ``pass``,
        ``elapsed_s``, ``photons`` per worker of each pass, ``preview``: the coarse preview, pass 0,
        of a large image, ``PREVIEW_PIXELS``) of the
        current job's newest pass, or None when there is none newer than the last returned.
        Raises RuntimeError with the server's traceback if the job failed."""
        failed = job_file(self.folder, "error", self.job)
        if os.path.exists(failed):
            with open(failed) as f:
                raise RuntimeError(f.read())
        try:
            with open(job_file(self.folder, "stats", self.job)) as f:
                stats = json.load(f)
            if self._shown == (self.job, stats["pass"]):
                return None
            # (written before its statistics: the image of their pass or of a later one, whose
            # statistics are then read again: a preview's are not a pass's)
            image = np.load(job_file(self.folder, "image", self.job))
            with open(job_file(self.folder, "stats", self.job)) as f:
                if json.load(f)["pass"] != stats["pass"]:
                    return None
        except (OSError, ValueError, KeyError):
            return None                 # nothing yet, or a file being replaced just now
        self._shown = (self.job, stats["pass"])
        return image, stats

    @property
    def running(self) -> bool:
        """Whether the current job may still bring a new image."""
        if self.proc is None or self.proc.poll() is not None or not self.job:
            return False
        return not any(os.path.exists(job_file(self.folder, kind, self.job)) for kind in ("done", "error"))

    def close(self):
        """Stop the server and remove the files."""
        if self.proc is not None:
            if self.job:
                open(job_file(self.folder, "stop", self.job), "w").close()
            try:
                if self.proc.poll() is None:
                    _send(self.proc, ("stop",))
                self.proc.wait(timeout=STOP_GRACE_S)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()
            for f in (self.proc.stdin, self.proc.stdout):
                try:
                    f.close()
                except OSError:
                    pass
            self.proc = None
        shutil.rmtree(self.folder, ignore_errors=True)

    def __del__(self):
        try:
            self.close()
        except Exception:           # (interpreter shutdown)
            pass


def serve():
    """The server process's loop: render each job read from stdin that no newer one superseded."""
    from .context import RenderContext
    from .integrator import render
    from .scene import Camera, Scene
    from .settings import RenderSettings

    inp = sys.stdin.buffer
    sys.stdout = sys.stderr
    parent = os.getppid()
    # The path of the scene last loaded, whether its context is still to be built, and the last
    # context built (of that scene, or of the one before, whose BVH the new one may keep).
    loaded, stale, ctx = None, True, None
    while True:
        try:
            msg = pickle.load(inp)
        except EOFError:
            return
        if msg[0] == "stop":
            return
        _, job, scene_path, camera, fields, folder = msg
        stop_path = job_file(folder, "stop", job)
        if os.path.exists(stop_path):
            continue

        def should_stop(stop_path=stop_path):
            return os.path.exists(stop_path) or os.getppid() != parent

        def publish(result, job=job, folder=folder, preview=False):
            image = np.ascontiguousarray(result.image, np.float32)
            _replace(job_file(folder, "image", job), lambda f: np.save(f, image))
            stats = {"pass": 0 if preview else len(result.stats), "elapsed_s": result.stats[-1]["elapsed_s"],
                     "photons": [int(s["photons_per_pass"]) for s in result.stats], "preview": preview}
            _replace(job_file(folder, "stats", job), lambda f: f.write(json.dumps(stats).encode()))
        try:
            settings = RenderSettings(**fields)
            camera = Camera(**camera)
            if scene_path != loaded:
                loaded, stale = None, True
                base = Scene.load(scene_path)
                loaded = scene_path
            if stale or ctx.glossy_through_roughness != settings.glossy_through_roughness:
                # (an edited scene keeps the last context's BVH if the edit left the triangles;
                # the last context is dropped, so its tables may become the new one's)
                ctx = RenderContext(dataclasses.replace(base, camera=camera).validate(),
                                    settings.glossy_through_roughness, reuse=ctx, take=True)
                stale = False
            else:
                ctx = ctx.with_camera(camera)
            small = preview_camera(camera)
            if small is not None:
                look = ctx.with_camera(small)
                render(look.source, dataclasses.replace(settings, passes=1, method="ppm"),
                       on_iteration=lambda result: publish(result, preview=True), should_stop=should_stop,
                       context=look)
            if not should_stop():
                # (after a preview, a newer job may end this one before its first pass)
                render(ctx.source, settings, on_iteration=publish, should_stop=should_stop, context=ctx,
                       stop_first_pass=small is not None)
            open(job_file(folder, "done", job), "w").close()
        except Exception:
            ctx, stale = None, True             # (a context left half changed is not reused)
            text = traceback.format_exc().encode()
            _replace(job_file(folder, "error", job), lambda f: f.write(text))
        if os.getppid() != parent:
            return


def preview_camera(camera):
    """``camera`` at the size of a job's preview (``PREVIEW_PIXELS``), or None where its image is
    small enough to need none."""
    x0, x1, y0, y1 = camera.window
    k = 1
    while (x1 - x0) * (y1 - y0) > PREVIEW_PIXELS * k * k:
        k *= 2
    w, h = camera.resolution
    return None if k == 1 else dataclasses.replace(camera, resolution=(max(1, w // k), max(1, h // k)))


def _same_but_camera(scene, other):
    """Whether ``scene`` holds the very objects of ``other`` (a Scene or None) but its camera."""
    return other is not None and all(getattr(scene, f.name) is getattr(other, f.name)
                                     for f in dataclasses.fields(scene) if f.name != "camera")


def _replace(path, write):
    """Write a file through ``write(binary file)`` under a temporary name, then move it to ``path``
    (a reader sees the old file or the new one, never half of one)."""
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        write(f)
    os.replace(tmp, path)
