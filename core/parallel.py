"""Worker pools: photon passes in this process or in worker processes.

Worker processes are plain Python interpreters (``sys.executable``, which inside
Blender is its bundled Python) that load this ``core`` package from its
directory under a private name, so the same code works from a checkout, from
the ``bpy`` module and from an installed extension (whose package name,
``bl_ext.<repo>.<id>.core``, does not exist in a fresh interpreter).  Messages
are pickles of plain tuples, dicts and NumPy arrays over the workers'
stdin/stdout; no class of ours crosses the process boundary.

The pool interface is ``submit(pass_index, target, n_photons, budget_s)``
followed by ``collect(should_stop)``: the integrator traces the next pass's eye
pass and builds its grid while the workers trace photons.  A worker ends its
share of a pass early (returning what it traced) when ``budget_s`` seconds have
passed since the submission, or when ``should_stop`` asks it to.  The
measurement points and their grid travel as ``.npy`` files that the workers map
into memory (in ``/dev/shm`` where it exists), so a 1080p pass costs no
pickling and no copy.
"""
from __future__ import annotations

import json
import os
import pickle
import selectors
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from .photon_pass import DepositTarget
from .worker import PhotonWorker

_BOOTSTRAP = r"""
import importlib.util, json, os, sys
# The parent's import path (inside Blender it holds the extension's wheels, e.g. embreex).
sys.path.extend(p for p in json.loads(os.environ.get("AMCMCPPM_SYS_PATH", "[]")) if p not in sys.path)
core_dir = sys.argv[1]
spec = importlib.util.spec_from_file_location("_amcmcppm_worker_core", core_dir + "/__init__.py",
                                              submodule_search_locations=[core_dir])
mod = importlib.util.module_from_spec(spec)
sys.modules["_amcmcppm_worker_core"] = mod
spec.loader.exec_module(mod)
# The entry point, "module.function" of the core (default: a photon worker).
module, function = (sys.argv[2] if len(sys.argv) > 2 else "parallel.worker_main").rsplit(".", 1)
getattr(importlib.import_module("_amcmcppm_worker_core." + module), function)()
"""


# Seconds a worker gets to return its partial pass after a stop request.
STOP_GRACE_S = 1.0


class WorkerError(RuntimeError):
    """A worker process failed; the message carries its traceback."""


class InProcessPool:
    """One worker in this process (``workers=1``): deterministic and without start-up cost."""

    def __init__(self, scene, settings, ctx=None):
        self.worker = PhotonWorker(scene, settings, 0, ctx=ctx, lane_halves=True)
        self._job = None

    @property
    def size(self) -> int:
        return 1

    def submit(self, pass_index, target, n_photons, budget_s=None, uniform=False):
        deadline = None if budget_s is None else time.perf_counter() + budget_s
        self._job = (pass_index, target, n_photons, deadline, uniform)

    def collect(self, should_stop=None):
        (pass_index, target, n_photons, deadline, uniform), self._job = self._job, None
        user_stop = should_stop or (lambda: False)
        stop = user_stop if deadline is None else (lambda: time.perf_counter() >= deadline or user_stop())
        return [self.worker.run_pass(pass_index, target, n_photons, should_stop=stop, uniform=uniform)]

    def close(self):
        pass


class ProcessPool:
    """``n`` worker processes, each with its own share of every pass and its own chains."""

    def __init__(self, scene, settings, n):
        self.procs = []
        self.settings = settings
        shm = "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None
        self.tmpdir = tempfile.mkdtemp(prefix="amcmcppm-", dir=shm)
        # Workers poll for this file between photon batches (a stop request mid-pass).
        self.stop_flag = os.path.join(self.tmpdir, "stop")
        self._pass_dir = None
        try:
            for i in range(n):
                self.procs.append(start_process("parallel.worker_main"))
            arrays = scene.to_arrays()
            settings_dict = {f: getattr(settings, f) for f in settings.__dataclass_fields__}
            for i, p in enumerate(self.procs):
                _send(p, ("init", arrays, settings_dict, i, self.stop_flag))
        except BaseException:
            self.close()
            raise
        # The workers build their scene while this process goes on; the first submit waits.
        self._starting = True

    @property
    def size(self) -> int:
        return len(self.procs)

    def submit(self, pass_index, target, n_photons, budget_s=None, uniform=False):
        if self._starting:
            for p in self.procs:
                self._receive(p)
            self._starting = False
        self._pass_dir = os.path.join(self.tmpdir, f"pass{pass_index}")
        os.makedirs(self._pass_dir)
        names = []
        for name, a in target.to_arrays().items():
            np.save(os.path.join(self._pass_dir, name + ".npy"), np.ascontiguousarray(a))
            names.append(name)
        for p in self.procs:
            _send(p, ("pass", pass_index, self._pass_dir, names, n_photons, budget_s, uniform))

    def collect(self, should_stop=None):
        """Wait for every worker's result.

        On ``should_stop()`` the workers are asked to stop after their current photon batch
        and return what they traced; those that do not answer within STOP_GRACE_S are
        killed.  Returns the results received (None if there are none).
        """
        results = [None] * len(self.procs)
        pending = set(range(len(self.procs)))
        sel = selectors.DefaultSelector()
        for i in pending:
            sel.register(self.procs[i].stdout, selectors.EVENT_READ, i)
        deadline = None
        try:
            while pending:
                for key, _ in sel.select(timeout=0.05):
                    i = key.data
                    results[i] = self._receive(self.procs[i])
                    pending.discard(i)
                    sel.unregister(key.fileobj)
                if pending and deadline is None and should_stop is not None and should_stop():
                    open(self.stop_flag, "w").close()
                    deadline = time.monotonic() + STOP_GRACE_S
                if pending and deadline is not None and time.monotonic() > deadline:
                    self.close(kill=True)
                    break
        finally:
            sel.close()
            if self._pass_dir:
                shutil.rmtree(self._pass_dir, ignore_errors=True)
                self._pass_dir = None
        got = [r for r in results if r is not None]
        return got or None

    def _receive(self, p):
        try:
            msg = pickle.load(p.stdout)
        except EOFError:
            code = p.wait()
            raise WorkerError(f"photon worker process exited unexpectedly (exit code {code})") from None
        if msg[0] == "error":
            raise WorkerError(f"photon worker failed:\n{msg[1]}")
        return msg[1]

    def close(self, kill=False):
        """Stop the workers (politely, or at once with ``kill``) and remove the shared files."""
        for p in self.procs:
            try:
                if kill:
                    p.kill()
                elif p.poll() is None:
                    _send(p, ("stop",))
            except OSError:
                pass
        deadline = time.monotonic() + 2.0
        for p in self.procs:
            try:
                p.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
            for f in (p.stdin, p.stdout):
                try:
                    f.close()
                except OSError:
                    pass
        self.procs = []
        shutil.rmtree(self.tmpdir, ignore_errors=True)


def make_pool(scene, settings, ctx=None):
    """In-process pool for one worker, worker processes otherwise."""
    n = settings.worker_count
    if n <= 1:
        return InProcessPool(scene, settings, ctx)
    return ProcessPool(scene, settings, n)


def start_process(entry):
    """A process of this Python (Blender's inside Blender) running ``entry``, "module.function" of
    the core, with pipes on its stdin and stdout and one thread for NumPy's libraries (the
    processes are the parallelism)."""
    env = dict(os.environ)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = "1"
    env["AMCMCPPM_SYS_PATH"] = json.dumps([p for p in sys.path if p])
    core_dir = os.path.dirname(os.path.abspath(__file__))
    return subprocess.Popen([_python_executable(), "-c", _BOOTSTRAP, core_dir, entry],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)


def _python_executable():
    """The interpreter for worker processes (inside Blender, its bundled Python)."""
    exe = sys.executable
    if exe and os.path.basename(exe).lower().startswith("python"):
        return exe
    # Blender older than 2.91 pointed sys.executable at itself; find its bundled Python.
    import sysconfig
    cand = os.path.join(sysconfig.get_paths()["scripts"], "python3" if os.name != "nt" else "python.exe")
    return cand if os.path.exists(cand) else exe


def _send(p, msg):
    pickle.dump(msg, p.stdin, protocol=pickle.HIGHEST_PROTOCOL)
    p.stdin.flush()


def worker_main():
    """Entry point of a worker process: serve requests from stdin until told to stop."""
    import traceback

    from .scene import Scene
    from .settings import RenderSettings

    inp = sys.stdin.buffer
    out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    sys.stdout = sys.stderr          # nothing else may write into the message channel
    worker = None
    while True:
        try:
            msg = pickle.load(inp)
        except EOFError:
            return
        try:
            if msg[0] == "stop":
                return
            if msg[0] == "init":
                _, arrays, settings_dict, index, stop_flag = msg
                worker = PhotonWorker(Scene.from_arrays(arrays), RenderSettings(**settings_dict), index)
                reply = ("ok", None)
            else:
                _, pass_index, folder, names, n_photons, budget_s, uniform = msg
                end = None if budget_s is None else time.perf_counter() + budget_s
                arrays = {name: np.load(os.path.join(folder, name + ".npy"), mmap_mode="r") for name in names}
                target = DepositTarget.from_arrays(arrays, worker.ctx.table)

                def stop():
                    return (end is not None and time.perf_counter() >= end) or os.path.exists(stop_flag)
                reply = ("ok", worker.run_pass(pass_index, target, n_photons, should_stop=stop,
                                               uniform=uniform))
        except Exception:
            reply = ("error", traceback.format_exc())
        pickle.dump(reply, out, protocol=pickle.HIGHEST_PROTOCOL)
        out.flush()
