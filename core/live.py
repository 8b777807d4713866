"""A render that runs in a process of its own and starts over when its scene or view changes.

This is what Blender's 3D viewport shows in Rendered shading (``amcmcppm_addon/viewport.py``):
the viewport asks for a new render whenever the user moves the view or edits the scene, and
must never wait for one.  :class:`LiveRender` keeps one server process (:func:`serve`, started
with :func:`core.parallel.start_process`) and sends it jobs: a scene file and settings.  The
server renders the newest job with :func:`core.render` in that process (one worker, no pool to
start), writes the image after every pass into the job's folder (a file replaced atomically),
and leaves a job as soon as a newer one supersedes it (a stop file, polled between photon
batches, as the photon workers poll theirs) or the process that sent it is gone.  Nothing here
runs in the caller's process but file reads: the viewport's Python thread never holds a
render, and the GIL is not shared with one.
"""
from __future__ import annotations

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

    def start(self, scene, settings):
        """Render ``scene`` (``core.Scene``) with ``settings`` (``RenderSettings``; one worker is
        used whatever they say) from now on, leaving the job before it."""
        if self.job:
            open(job_file(self.folder, "stop", self.job), "w").close()
        self.job += 1
        path = job_file(self.folder, "scene", self.job)
        # (uncompressed, unlike Scene.save: the caller, the viewport's redraw, waits for it)
        np.savez(path, **scene.to_arrays())
        for name in os.listdir(self.folder):
            # The files of earlier jobs, but their stop files: the server skips a job still
            # queued in its pipe by its stop file.
            m = re.fullmatch(r"(scene|image|stats|error|done)(\d+)\.\w+", name)
            if m and int(m.group(2)) < self.job:
                try:
                    os.remove(os.path.join(self.folder, name))
                except OSError:
                    pass
        if self.proc is None or self.proc.poll() is not None:
            self.proc = start_process("live.serve")
        fields = {f: getattr(settings, f) for f in settings.__dataclass_fields__}
        fields["workers"] = 1
        _send(self.proc, ("render", self.job, path, fields, self.folder))

    def latest(self):
        """(image (h, w, 4) float32 linear RGBA, top row first; the job's statistics: ``pass``,
        ``elapsed_s``, ``photons`` per worker of each pass) of the
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
            # (written before its statistics: the image of their pass or of a later one)
            image = np.load(job_file(self.folder, "image", self.job))
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
    from .integrator import render
    from .scene import Scene
    from .settings import RenderSettings

    inp = sys.stdin.buffer
    sys.stdout = sys.stderr
    parent = os.getppid()
    while True:
        try:
            msg = pickle.load(inp)
        except EOFError:
            return
        if msg[0] == "stop":
            return
        _, job, scene_path, fields, folder = msg
        stop_path = job_file(folder, "stop", job)
        if os.path.exists(stop_path):
            continue

        def should_stop(stop_path=stop_path):
            return os.path.exists(stop_path) or os.getppid() != parent

        def publish(result, job=job, folder=folder):
            image = np.ascontiguousarray(result.image, np.float32)
            _replace(job_file(folder, "image", job), lambda f: np.save(f, image))
            stats = {"pass": len(result.stats), "elapsed_s": result.stats[-1]["elapsed_s"],
                     "photons": [int(s["photons_per_pass"]) for s in result.stats]}
            _replace(job_file(folder, "stats", job), lambda f: f.write(json.dumps(stats).encode()))
        try:
            render(Scene.load(scene_path), RenderSettings(**fields), on_iteration=publish,
                   should_stop=should_stop)
            open(job_file(folder, "done", job), "w").close()
        except Exception:
            text = traceback.format_exc().encode()
            _replace(job_file(folder, "error", job), lambda f: f.write(text))
        if os.getppid() != parent:
            return


def _replace(path, write):
    """Write a file through ``write(binary file)`` under a temporary name, then move it to ``path``
    (a reader sees the old file or the new one, never half of one)."""
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        write(f)
    os.replace(tmp, path)
