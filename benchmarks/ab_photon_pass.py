"""A/B of the photon pass: this checkout's ``core`` against ``core`` at another git revision.

Both versions are imported into one process (the other one as ``core_base``, extracted with
``git archive``) and traced alternately on the same scene, eye pass and random numbers, so
each round's ratio is taken under the same machine load; the median and range over rounds
are printed.  Use it before claiming that a change to the photon pass is faster.

    python benchmarks/ab_photon_pass.py [--base HEAD] [--scene cornell_box] [--resolution 640 480]
                                        [--rounds 10] [--paths 65536]
                                        [--pairs | --render METHOD | --stage eye|grid]
                                        [--workers N] [--photons-per-pass N] [--isotropic]
                                        [--materials VARIANT]

``--stage eye|grid`` times one stage of what the main process prepares for each pass instead:
the eye pass, or the grid of the measurement points (of one eye pass's points).
``--pairs`` traces as the Markov chains do (deposit pairs collected per path) instead of
splatting uniform photons into per-point sums.  ``--render ppm|amcmcppm`` times whole
renders instead (eye passes, grids, chains and their deposit logs included; one worker
unless ``--workers N``) and compares photon paths per second, the first pass (start-up) left out.
``--materials`` gives the scene's diffuse materials one of ``layer_cost.py``'s bases (e.g.
``metal_curve``: every wall a rough gold, so that every deposit pair is a glossy one).
"""
from __future__ import annotations

import argparse
import importlib
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
BATCH = 1 << 14

from core.testing.scenes import BUILTIN  # noqa: E402


def extract(rev, into, package="core_base"):
    """``core`` at git revision ``rev`` as the package ``package`` under directory ``into``."""
    archive = subprocess.run(["git", "-C", ROOT, "archive", f"--prefix={package}/", f"{rev}:core"],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", into], input=archive, check=True)


def first_eye_pass(package, scene_name, resolution, edit=None):
    """(module getter, default settings, render context, eye-pass function) of the built-in scene
    with ``package``; ``edit(scene)``, if given, changes the scene first and returns it."""
    mod = lambda name: importlib.import_module(f"{package}.{name}")  # noqa: E731
    settings = importlib.import_module(package).RenderSettings()
    scene = mod("testing.scenes").BUILTIN[scene_name](resolution=resolution)
    if edit is not None:
        scene = edit(scene)
    ctx = mod("context").RenderContext(scene)
    trace = lambda: mod("eye_pass").trace_eye_pass(ctx, np.random.default_rng(0),  # noqa: E731
                                                    settings.initial_radius_px, settings.max_bounces)
    return mod, settings, ctx, trace


def photon_pass(package, scene_name, resolution, n_paths, pairs, edit=None):
    """A function tracing ``n_paths`` photons with ``package``; returns vertices per second.
    ``edit(scene)``, if given, changes the built-in scene first and returns it."""
    mod, settings, ctx, trace = first_eye_pass(package, scene_name, resolution, edit)
    eye = trace()
    pp = mod("photon_pass")
    vol = getattr(eye, "volume", None)            # (revisions with scattering volumes)
    extra = ({"volume": vol, "volume_radius": vol.base_radius, "media": ctx.anisotropy}
             if vol is not None and vol.count else {})
    target = pp.DepositTarget(eye.points, eye.points.base_radius, ctx.table, resolution[0] * resolution[1],
                              ctx.has_shading_normals, **extra)
    dims = pp.path_dims(settings.max_bounces)

    def run():
        rng = np.random.default_rng(1)
        vertices = 0
        t0 = time.perf_counter()
        for done in range(0, n_paths, BATCH):
            u = rng.random((min(BATCH, n_paths - done), dims))
            vertices += pp.trace_photons(ctx, target, u, settings.max_bounces, collect_pairs=pairs).vertices
        return vertices / (time.perf_counter() - t0)
    return run


def main_stage(package, scene_name, resolution, stage, edit=None):
    """A function timing one stage of what the main process prepares for a pass with ``package``:
    the eye pass (``"eye"``) or the measurement points' grid (``"grid"``, of the first eye pass's
    points); returns stages per second."""
    mod, _, _, trace = first_eye_pass(package, scene_name, resolution, edit)
    points = trace().points
    grid = lambda: mod("hash_grid").HashGrid(points.position, points.base_radius, points.ng)  # noqa: E731
    work = trace if stage == "eye" else grid

    def run():
        t0 = time.perf_counter()
        work()
        return 1.0 / (time.perf_counter() - t0)
    return run


def whole_render(package, scene_name, resolution, method, passes, workers, photons=None, edit=None):
    """A function rendering with ``package`` on ``workers``; returns traced paths per second."""
    core = importlib.import_module(package)
    scene = importlib.import_module(f"{package}.testing.scenes").BUILTIN[scene_name](resolution=resolution)
    if edit is not None:
        scene = edit(scene)
    extra = {"photons_per_pass": photons} if photons else {}
    settings = core.RenderSettings(method=method, workers=workers, passes=passes, **extra)

    def run():
        stats = core.render(scene, settings).stats
        return sum(s["paths_traced"] for s in stats[1:]) / (stats[-1]["elapsed_s"] - stats[0]["elapsed_s"])
    return run


def interleaved_rates(runs, rounds):
    """{name: [rate per round]} of the functions ``runs`` (name -> function returning a rate), after
    one warm-up call each, taking turns in an order that reverses every round (the machines are
    shared: neighbours' load falls on all alike)."""
    rates = {name: [] for name in runs}
    for run in runs.values():
        run()                                        # warm-up
    for r in range(rounds):
        for name in (list(runs) if r % 2 == 0 else list(runs)[::-1]):
            rates[name].append(runs[name]())
    return rates


def isotropic(scene):
    """``scene`` with every volume's anisotropy (materials' and the world's) set to 0."""
    if scene.materials.volume_anisotropy is not None:
        scene.materials.volume_anisotropy[:] = 0.0
    scene.world.volume_anisotropy = 0.0
    return scene


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="HEAD", help="git revision to compare against (default HEAD)")
    ap.add_argument("--scene", default="cornell_box", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(640, 480))
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--paths", type=int, default=65536, help="photon paths per round and version")
    how = ap.add_mutually_exclusive_group()
    how.add_argument("--pairs", action="store_true", help="collect deposit pairs (as the chains do)")
    how.add_argument("--render", choices=("ppm", "amcmcppm"), help="time whole renders")
    how.add_argument("--stage", choices=("eye", "grid"),
                     help="time one stage of the main process's preparation: the eye pass or the grid")
    ap.add_argument("--passes", type=int, default=4, help="passes per render (with --render)")
    ap.add_argument("--workers", type=int, default=1, help="worker count of the renders (with --render)")
    ap.add_argument("--photons-per-pass", type=int, default=None,
                    help="photons per pass and worker of the renders (default: each version's own)")
    ap.add_argument("--isotropic", action="store_true",
                    help="the scene's volumes scatter evenly (anisotropy 0, Cycles' default)")
    ap.add_argument("--materials", default=None,
                    help="a layer_cost.py base for the diffuse materials (e.g. metal_curve)")
    a = ap.parse_args()
    edit = isotropic if a.isotropic else None
    if a.materials:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        from layer_cost import with_base
        edit = (lambda scene, f=edit: with_base(scene if f is None else f(scene), a.materials))
    with tempfile.TemporaryDirectory() as tmp:
        extract(a.base, tmp)
        sys.path.insert(0, tmp)
        res = tuple(a.resolution)
        versions = {name: (whole_render(pkg, a.scene, res, a.render, a.passes, a.workers, a.photons_per_pass, edit)
                           if a.render else
                           main_stage(pkg, a.scene, res, a.stage, edit) if a.stage else
                           photon_pass(pkg, a.scene, res, a.paths, a.pairs, edit))
                    for name, pkg in (("base", "core_base"), ("this", "core"))}
        rates = interleaved_rates(versions, a.rounds)
    ratio = np.array(rates["this"]) / np.array(rates["base"])
    if a.render:
        what, unit = f"{a.render} renders of {a.passes} passes on {a.workers} worker(s)", "paths/s"
        if a.photons_per_pass:
            what += f", {a.photons_per_pass:,} photons per pass and worker"
    elif a.stage:
        what, unit = f"the {'eye pass' if a.stage == 'eye' else 'grid build'}", f"{a.stage}s/s"
    else:
        what, unit = f"{'pairs' if a.pairs else 'splat'}, {a.paths} paths", "vertices/s"
    print(f"{a.scene} {a.resolution[0]}x{a.resolution[1]}, {a.rounds} rounds of {what}: "
          f"base ({a.base}) {np.median(rates['base']):,.0f} {unit}, this checkout "
          f"{np.median(rates['this']):,.0f}; this/base median {np.median(ratio):.3f} "
          f"(range {ratio.min():.3f}-{ratio.max():.3f})")


if __name__ == "__main__":
    main()
