"""Light portals: photons from afar aimed through the windows an artist marked (``World.portals``).

Cycles' light portals (area lights marked Portal, in a room's windows) guide its sampling of the
world; here they aim the photons from afar (the world's and the sun's) through the windows
(``core.lights.Focus.through``), with the chance 1/2, every photon's flux divided by the density of
that mixture.  This renders, for the same time each, with and without the portals, PPM and
AMCMCPPM (one worker a run, 2 runs at a time; with the portals also with an eighth of the automatic
photon count, ``-small``: the aimed photons enter and bounce, so a pass costs more; ``-sampled``:
with ``direct_light="sampled"``, whose world light samples the portals guide too; ``auto``:
``RenderSettings.method``), against a
reference of PPM with the portals at a quarter of the initial radius (``--reference-time`` seconds,
2 workers; its direct light from photons, so its kernel bias, a sixteenth of a run's, counts
against the light samples alone):

* ``window``: a closed room of 4 x 4 x 2.5 m lit only by a constant white sky through a square
  window of 0.3 m in one wall (``direct_light_window.window_room``), one portal in the window;
* ``hole``: the paper's second scene (``hole_mirror_glass``: the sun through a hole of 0.15 m onto
  a mirror that throws it through a glass sphere), one portal in the hole;
* ``stained_window``: the sample .blend (the sun and a dim sky through leaves and a stained-glass
  window of 1.6 x 1.4 m, a lamp panel in the room), exported once by the add-on with its portal
  (``--out``/stained_window_WxH.npz), rendered with and without it.

    python benchmarks/portal_cost.py --time 30 --seeds 3 [--scenes window hole stained_window]

prints MSE / mean(R)^2 per seed (relMSE = mean((I - R)^2 / (R^2 + 0.01)) is dominated by its 0.01
on these dark images) over the whole image and over the room alone: without the pixels where the
reference is brighter than 10 times its median (the sky seen through the window) and 2 pixels
around them, whose edges converge by passes (one jittered camera ray a pixel and pass), not by
photons; and the passes each run made.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

KINDS = ("ppm", "ppm-portal", "ppm-portal-small", "amcmcppm", "amcmcppm-portal", "amcmcppm-portal-small",
         "ppm-sampled", "ppm-portal-sampled", "amcmcppm-sampled", "amcmcppm-portal-sampled",
         "auto", "auto-portal")
SMALL = 12_500          # photons per pass and worker of the "-small" kinds (the automatic count: 100,000)


def export_sample(name, resolution, path):
    """Export sample_blends/``name``.blend at ``resolution`` to ``path`` (.npz) with the add-on."""
    import bpy

    from render import ensure_addon
    ensure_addon(bpy)
    bpy.ops.wm.open_mainfile(filepath=os.path.join(ROOT, "sample_blends", f"{name}.blend"))
    r = bpy.context.scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = *resolution, 100
    export = sys.modules["amcmcppm"].amcmcppm_addon.export
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    exported.scene.save(path)


def portal_scene(name, portal, resolution=(64, 48), out="."):
    """The scene ``name`` ("window", "hole" or "stained_window", exported into ``out``), with its
    portal if ``portal``."""
    if name == "stained_window":
        from core import Scene
        scene = Scene.load(os.path.join(out, f"{name}_{resolution[0]}x{resolution[1]}.npz"))
        if not portal:
            scene.world.portals = scene.world.portal_disks = None
        return scene.validate()
    if name == "window":
        from direct_light_window import window_room
        scene, centre, half = window_room(0.3, resolution), (2.0, 0.0, 1.6), 0.15
    else:
        from core.testing.scenes import hole_mirror_glass
        scene, centre, half = hole_mirror_glass(resolution), (2.0, 0.0, 1.9), 0.075
    if portal:
        # (in the wall x = 2, light crossing it along -x: u x v = (-half^2, 0, 0))
        scene.world.portals = np.array([[centre, (0.0, 0.0, half), (0.0, half, 0.0)]])
        scene.world.portal_disks = np.zeros(1, bool)
    return scene.validate()


def run_one(scene, kind, seed, seconds, out, resolution):
    """One render in this process."""
    from core import RenderSettings, render
    base = RenderSettings()
    if kind == "reference":
        kw = dict(method="ppm", initial_radius_px=0.25 * base.initial_radius_px, workers=2)
    else:
        kw = dict(method=kind.split("-")[0], workers=1,
                  photons_per_pass=SMALL if kind.endswith("small") else 0,
                  direct_light="sampled" if kind.endswith("sampled") else "photons")
    r = render(portal_scene(scene, kind == "reference" or "portal" in kind, resolution,
                            os.path.dirname(out)),
               RenderSettings(seed=seed, passes=0, time_limit=seconds, **kw))
    np.save(out, r.image[..., :3])
    with open(out + ".json", "w") as f:
        json.dump({"passes": len(r.stats), "portals": r.stats[-1].get("focus_portals", 0)}, f)


def away_from_bright(ref, factor=10.0, margin=2):
    """(H, W) bool: the pixels of ``ref`` (H, W, 3) not within ``margin`` pixels of one brighter than
    ``factor`` times the image's median."""
    lum = ref.mean(axis=2)
    near = lum > factor * np.median(lum)
    for _ in range(margin):
        grown = near.copy()
        grown[1:] |= near[:-1]
        grown[:-1] |= near[1:]
        grown[:, 1:] |= near[:, :-1]
        grown[:, :-1] |= near[:, 1:]
        near = grown
    return ~near


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["window", "hole"],
                    choices=["window", "hole", "stained_window"])
    ap.add_argument("--resolution", nargs=2, type=int, default=[64, 48])
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    ap.add_argument("--time", type=float, default=30.0, help="seconds per run")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--reference-time", type=float, default=180.0)
    ap.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "portal_cost"))
    ap.add_argument("--run-one", nargs=4, metavar=("SCENE", "KIND", "SEED", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.run_one:
        scene, kind, seed, out = a.run_one
        if kind == "export":
            return export_sample(scene, a.resolution, out)
        return run_one(scene, kind, int(seed), a.reference_time if kind == "reference" else a.time, out,
                       a.resolution)
    os.makedirs(a.out, exist_ok=True)
    size = f"{a.resolution[0]}x{a.resolution[1]}"

    def spawn(scene, kind, seed):
        name = f"{scene}_{size}.npz" if kind == "export" else f"{scene}_{size}_{kind}_{seed}.npy"
        out = os.path.join(a.out, name)
        if not os.path.exists(out):
            cmd = [sys.executable, os.path.abspath(__file__), "--time", str(a.time), "--reference-time",
                   str(a.reference_time), "--resolution", *map(str, a.resolution), "--run-one", scene, kind,
                   str(seed), out]
            subprocess.run(cmd, check=True)
        return out

    for scene in a.scenes:
        if scene == "stained_window":
            spawn(scene, "export", 0)
        ref = np.load(spawn(scene, "reference", 1000))
        with ThreadPoolExecutor(2) as pool:
            runs = {(k, s): pool.submit(spawn, scene, k, s) for s in range(1, a.seeds + 1) for k in a.kinds}
            paths = {key: f.result() for key, f in runs.items()}
        print(f"\n{scene}, {size}: {a.time:g} s a run, reference {a.reference_time:g} s "
              f"(mean {ref.mean():.5f})")
        room = away_from_bright(ref)
        print(f"(the room: {room.sum()} of {room.size} pixels)")
        print("| method | MSE / mean(R)^2 per seed | median | the room's, per seed | median | passes |\n"
              "|---|---|---|---|---|---|")
        for kind in a.kinds:
            seeds = range(1, a.seeds + 1)
            sq = [(np.load(paths[kind, s]) - ref) ** 2 for s in seeds]
            err = [np.mean(e) / ref.mean() ** 2 for e in sq]
            inside = [np.mean(e[room]) / ref[room].mean() ** 2 for e in sq]
            passes = [json.load(open(paths[kind, s] + ".json"))["passes"] for s in seeds]
            print(f"| {kind} | {', '.join(f'{x:.3g}' for x in err)} | {np.median(err):.3g} | "
                  f"{', '.join(f'{x:.3g}' for x in inside)} | {np.median(inside):.3g} | "
                  f"{', '.join(str(p) for p in passes)} |")


if __name__ == "__main__":
    main()
