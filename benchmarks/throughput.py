"""Throughput: photon tracing against raw embree, worker scaling, AMCMCPPM overhead, peak memory.

Every figure is a ratio measured in this one run (the machines are shared and noisy):

1. photon path vertices per second of the real photon pass (tracing, deposits into the
   measurement points of a real eye pass, Russian roulette) against embreex closest-hit rays
   per second, replaying the very rays the photon pass cast, with the same batch sizes;
2. the same without measurement points (tracing and scattering only);
3. photon paths per second of whole renders with 2 workers against 1 worker (SPPM, AMCMCPPM);
4. AMCMCPPM traced paths (and vertices) per second against SPPM's, same scene
   (3 and 4: medians over interleaved rounds, each ratio taken within a round);
5. peak memory of a 1920x1080 render at default settings (main process plus the largest worker).

    python benchmarks/throughput.py [--scene cornell_box] [--resolution 640 480] [--rounds 3]
                                    [--json out.json] [--photons-per-pass N]

``--subdivide K`` splits every triangle into 4**K (same surfaces, same image): only the ray
cost changes, which shows how the ratio of 1. depends on the scene's geometry.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core import RenderSettings, render  # noqa: E402
from core.accel import Accel  # noqa: E402
from core.context import RenderContext  # noqa: E402
from core.eye_pass import trace_eye_pass  # noqa: E402
from core.photon_pass import DepositTarget, path_dims, trace_photons  # noqa: E402
from core.testing.scenes import BUILTIN, subdivide  # noqa: E402
from core.worker import PPM_BATCH  # noqa: E402


class RecordingAccel(Accel):
    """An Accel that keeps a copy of every ray batch it is asked to intersect."""

    def __init__(self, scene):
        super().__init__(scene)
        self.batches = []

    def intersect(self, origins, directions, tmax=None):
        self.batches.append((np.ascontiguousarray(origins, np.float32),
                             np.ascontiguousarray(directions, np.float32)))
        return super().intersect(origins, directions, tmax)


def photon_pass_rate(scene, n_paths, with_points, settings):
    """(vertices per second, rays per second of the replayed batches, batch count)."""
    ctx = RenderContext(scene)
    ctx.accel = RecordingAccel(scene)
    ctx.lights.accel = ctx.accel
    w, h = scene.camera.resolution
    eye = trace_eye_pass(ctx, np.random.default_rng(0), settings.initial_radius_px, settings.max_bounces)
    points = eye.points if with_points else eye.points.take(np.zeros(0, np.int64))
    target = DepositTarget(points, points.base_radius, ctx.table, w * h, ctx.has_shading_normals)
    ctx.accel.batches.clear()
    rng = np.random.default_rng(1)
    d = path_dims(settings.max_bounces)
    vertices = 0
    t0 = time.perf_counter()
    done = 0
    while done < n_paths:
        b = min(PPM_BATCH, n_paths - done)
        batch = trace_photons(ctx, target, rng.random((b, d)), settings.max_bounces)
        vertices += batch.vertices
        done += b
    t_photons = time.perf_counter() - t0
    # Replay exactly those rays through embree, batch by batch.
    batches = ctx.accel.batches
    rays = sum(len(o) for o, _ in batches)
    embree = ctx.accel._embree
    t0 = time.perf_counter()
    for o, dirs in batches:
        embree.run(o, dirs, output=1)
    t_rays = time.perf_counter() - t0
    return vertices / t_photons, rays / t_rays, len(batches), rays, vertices, target.grid.entry_count


def render_rate(scene, **kw):
    s = RenderSettings(**kw)
    result = render(scene, s)
    st = result.stats
    # Skip the first pass (worker start-up, chain initialisation).
    t = st[-1]["elapsed_s"] - st[0]["elapsed_s"]
    paths = sum(x["paths_traced"] for x in st[1:])
    vertices = sum(x["photon_vertices"] for x in st[1:])
    return paths / t, vertices / t


def peak_memory(resolution, timeout=900, base=None):
    """Peak RSS (MiB) of a default-settings render at ``resolution`` in a fresh process; ``base``:
    a variant of ``layer_cost.with_base`` for the diffuse materials (e.g. "metal_brushed")."""
    code = f"""
import resource, sys, json
sys.path.insert(0, {ROOT!r})
sys.path.insert(0, {os.path.join(ROOT, "benchmarks")!r})
from core import render, RenderSettings
from core.testing.scenes import cornell_box
from layer_cost import with_base
scene = cornell_box({tuple(resolution)!r})
if {base!r} is not None:
    scene = with_base(scene, {base!r})
r = render(scene, RenderSettings(passes=2))
print(json.dumps({{"main": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "worker": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
                  "workers": r.stats[-1]["workers"], "points": r.stats[-1]["measurement_points"],
                  "grid_entries": r.stats[-1]["grid_entries"]}}))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    if out.returncode:
        raise RuntimeError(out.stderr)
    return json.loads(out.stdout.strip().splitlines()[-1])


def render_ratios(scene, a, out):
    """Figures 3 and 4 into ``out``."""
    # Whole renders, interleaved in rounds: the machine's load drifts, so every ratio is taken
    # within a round and the median over rounds is reported with its range.
    common = dict(passes=a.passes, photons_per_pass=a.photons_per_pass)
    configs = [(m, w) for w in (1, 2) for m in ("ppm", "amcmcppm")]
    ratios = {}
    for r in range(a.rounds):
        rates = {}
        for method, workers in configs:
            rates[method, workers] = render_rate(scene, method=method, workers=workers, **common)
            p, v = rates[method, workers]
            print(f"round {r + 1}: render {method:9s} workers {workers}: {p:10,.0f} paths/s "
                  f"{v:12,.0f} vertices/s")
        for method in ("ppm", "amcmcppm"):
            ratios.setdefault(f"{method}_two_worker_speedup", []).append(
                rates[method, 2][0] / rates[method, 1][0])
        for workers in (1, 2):
            for k, name in ((0, "paths"), (1, "vertices")):
                ratios.setdefault(f"amcmcppm_over_ppm_{name}_w{workers}", []).append(
                    rates["amcmcppm", workers][k] / rates["ppm", workers][k])
    for key, values in ratios.items():
        out[key] = float(np.median(values))
        out[key + "_range"] = [float(min(values)), float(max(values))]
    for method in ("ppm", "amcmcppm"):
        key = f"{method}_two_worker_speedup"
        print(f"{method}: 2 workers / 1 worker = {out[key]:.2f}x (median of {a.rounds} rounds; "
              f"range {out[key + '_range'][0]:.2f}-{out[key + '_range'][1]:.2f})")
    for workers in (1, 2):
        rp, rv = out[f"amcmcppm_over_ppm_paths_w{workers}"], out[f"amcmcppm_over_ppm_vertices_w{workers}"]
        lo, hi = out[f"amcmcppm_over_ppm_paths_w{workers}_range"]
        print(f"AMCMCPPM / SPPM, {workers} worker(s): traced paths/s {rp:.2f} (range {lo:.2f}-{hi:.2f}), "
              f"vertices/s {rv:.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="cornell_box", choices=sorted(BUILTIN))
    ap.add_argument("--resolution", type=int, nargs=2, default=(640, 480))
    ap.add_argument("--paths", type=int, default=200_000, help="photon paths for the vertex rate")
    ap.add_argument("--passes", type=int, default=5, help="passes of the render-rate runs")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds of the render-rate runs")
    ap.add_argument("--subdivide", type=int, default=0, metavar="K",
                    help="split every triangle into 4**K (dearer rays, same light transport)")
    ap.add_argument("--photons-per-pass", type=int, default=RenderSettings().photons_per_pass,
                    help="photons per pass and worker of the render-rate runs (default: automatic)")
    ap.add_argument("--skip-memory", action="store_true")
    ap.add_argument("--memory-base", default=None,
                    help="the 1080p memory with the diffuse materials made this layer_cost.py variant "
                         "(e.g. metal_brushed)")
    ap.add_argument("--skip-renders", action="store_true", help="only the photon-pass figures 1 and 2")
    ap.add_argument("--json", help="also write the figures to this JSON file")
    a = ap.parse_args()
    scene = BUILTIN[a.scene](resolution=tuple(a.resolution))
    if a.subdivide:
        scene = subdivide(scene, a.subdivide)
    s = RenderSettings()
    out = {"scene": a.scene, "resolution": list(a.resolution), "triangles": scene.triangle_count,
           "cpu_count": os.cpu_count()}
    print(f"scene {a.scene} {a.resolution[0]}x{a.resolution[1]}, {scene.triangle_count} triangles")

    v_rate, r_rate, n_batches, rays, vertices, entries = photon_pass_rate(scene, a.paths, True, s)
    out.update(photon_vertices_per_s=v_rate, embree_rays_per_s=r_rate, vertex_ray_ratio=v_rate / r_rate,
               ray_batches=n_batches, rays=rays, grid_entries=entries)
    print(f"photon pass (deposits)   {v_rate:12,.0f} vertices/s   embree {r_rate:12,.0f} rays/s   "
          f"ratio {v_rate / r_rate:.3f}   ({n_batches} batches, {rays:,} rays)")
    v0, r0, *_ = photon_pass_rate(scene, a.paths, False, s)
    out.update(trace_only_vertices_per_s=v0, trace_only_ratio=v0 / r0)
    print(f"photon pass (no points)  {v0:12,.0f} vertices/s   embree {r0:12,.0f} rays/s   ratio {v0 / r0:.3f}")

    if not a.skip_renders:
        render_ratios(scene, a, out)
    if not (a.skip_memory or a.skip_renders):
        mem = peak_memory((1920, 1080), base=a.memory_base)
        out["peak_memory_1080p_mib"] = mem
        total = mem["main"] + mem["worker"] * max(mem["workers"] - 1, 0) + (mem["worker"] if mem["workers"] > 1 else 0)
        out["peak_memory_1080p_total_mib"] = total
        print(f"1920x1080 default settings: main {mem['main']:.0f} MiB, largest worker {mem['worker']:.0f} MiB "
              f"x {mem['workers']} workers, total at most {total:.0f} MiB")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=2)


if __name__ == "__main__":
    main()
