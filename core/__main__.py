"""Command line: ``python -m core render scene.npz --output out.exr [options]``."""
from __future__ import annotations

import argparse
import json
import sys
import time

from .scene import Scene, SceneError
from .settings import (AOV_PREFIX, AUTO_RAMP, DATA_PASSES, DIRECT_LIGHT, LIGHTGROUP_PREFIX,
                       MAX_TRANSPARENT_BOUNCES, METHODS, MUTATIONS, NORMALISATIONS, PIXEL_JITTER,
                       RenderSettings)


def build_parser():
    p = argparse.ArgumentParser(prog="python -m core", description="AMCMCPPM rendering core")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a scene file (.npz) or a built-in scene")
    src = r.add_mutually_exclusive_group(required=True)
    src.add_argument("scene", nargs="?", help="scene written by Scene.save (.npz)")
    src.add_argument("--builtin", help="built-in scene name (see core/testing/scenes.py)")
    r.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"),
                   help="resolution of a built-in scene")
    r.add_argument("--output", "-o", required=True, help="EXR file to write (linear RGBA)")
    r.add_argument("--png", help="also write a display-referred PNG")
    d = RenderSettings()
    r.add_argument("--passes", type=int, default=d.passes, help="passes (0 = until --time-limit)")
    r.add_argument("--time-limit", type=float, default=d.time_limit, help="seconds (0 = no limit)")
    r.add_argument("--seed", type=int, default=d.seed)
    r.add_argument("--method", choices=METHODS, default=d.method)
    r.add_argument("--target-acceptance", type=float, default=d.target_acceptance)
    r.add_argument("--mutation", choices=MUTATIONS, default=d.mutation)
    r.add_argument("--normalisation", choices=NORMALISATIONS, default=d.normalisation)
    r.add_argument("--photons-per-pass", type=int, default=d.photons_per_pass,
                   help="photon paths per pass and worker (0 = automatic: grows with the image)")
    r.add_argument("--first-pass-photons", type=int, default=d.first_pass_photons,
                   help=f"photon paths per worker in the first pass, growing {AUTO_RAMP} times a pass up to "
                        "--photons-per-pass (0 = automatic)")
    r.add_argument("--chains", type=int, default=d.chains)
    r.add_argument("--initial-radius", type=float, default=d.initial_radius_px,
                   help="initial gather radius in pixel footprints")
    r.add_argument("--alpha", type=float, default=d.alpha)
    r.add_argument("--direct-light", choices=DIRECT_LIGHT, default=d.direct_light,
                   help="light straight from emitters from the photons or from light samples")
    r.add_argument("--direct-samples", type=int, default=d.direct_samples,
                   help="light samples per pixel and pass (--direct-light sampled)")
    r.add_argument("--pixel-jitter", choices=PIXEL_JITTER, default=d.pixel_jitter,
                   help="where in its pixel (and on the lens) each pass's camera ray starts, which lobes it "
                        "takes and where its light samples fall (stratified over the passes, or random)")
    r.add_argument("--focus-photons", action=argparse.BooleanOptionalAction, default=d.focus_photons,
                   help="aim uniform photons from the sun and the world at what the camera sees, or "
                        "through the scene's light portals, where that pays (--no-focus-photons: off)")
    r.add_argument("--bias-correction", action=argparse.BooleanOptionalAction, default=d.bias_correction,
                   help="correct the image for the gather radius's blur (--no-bias-correction: off)")
    r.add_argument("--max-bounces", type=int, default=d.max_bounces,
                   help="most bounces of a light path (Cycles' Total)")
    r.add_argument("--diffuse-bounces", type=int, default=d.diffuse_bounces)
    r.add_argument("--glossy-bounces", type=int, default=d.glossy_bounces)
    r.add_argument("--transmission-bounces", type=int, default=d.transmission_bounces)
    r.add_argument("--volume-bounces", type=int, default=d.volume_bounces)
    r.add_argument("--transparent-bounces", type=int, default=d.transparent_max_bounces,
                   help="most transparent surfaces a light path crosses (Cycles' Transparent; "
                        f"{MAX_TRANSPARENT_BOUNCES}: not counted)")
    for name, what in (("reflective", "off mirrors, glossy lobes and glass"),
                       ("refractive", "through glass")):
        r.add_argument(f"--caustics-{name}", action=argparse.BooleanOptionalAction,
                       default=getattr(d, f"caustics_{name}"),
                       help=f"light {what} lights diffuse surfaces (Cycles' {name.title()} Caustics)")
    r.add_argument("--glossy-through", type=float, default=d.glossy_through_roughness,
                   help="camera paths go on through glossy lobes smoother than this roughness")
    r.add_argument("--workers", type=int, default=d.workers, help="0 = one per CPU core")
    r.add_argument("--data-passes", nargs="+", default=(), metavar="PASS",
                   help="data passes written into the EXR beside the image, as channels PASS.R, PASS.G, "
                        "PASS.B (PASS.V of one-channel passes): any of "
                        f"{', '.join(DATA_PASSES)}, '{AOV_PREFIX}' + a Shader AOV's name, "
                        f"'{LIGHTGROUP_PREFIX}' + a light group's name")
    r.add_argument("--stats", help="write per-pass statistics as JSON lines to this file")
    r.add_argument("--quiet", "-q", action="store_true")
    return p


def settings_from_args(a) -> RenderSettings:
    return RenderSettings(method=a.method, passes=a.passes, time_limit=a.time_limit,
                          photons_per_pass=a.photons_per_pass,
                          first_pass_photons=a.first_pass_photons, seed=a.seed, alpha=a.alpha,
                          initial_radius_px=a.initial_radius, max_bounces=a.max_bounces,
                          diffuse_bounces=a.diffuse_bounces, glossy_bounces=a.glossy_bounces,
                          transmission_bounces=a.transmission_bounces, volume_bounces=a.volume_bounces,
                          caustics_reflective=a.caustics_reflective,
                          caustics_refractive=a.caustics_refractive,
                          transparent_max_bounces=a.transparent_bounces,
                          workers=a.workers, chains=a.chains, target_acceptance=a.target_acceptance,
                          mutation=a.mutation, normalisation=a.normalisation,
                          glossy_through_roughness=a.glossy_through, bias_correction=a.bias_correction,
                          direct_light=a.direct_light, direct_samples=a.direct_samples,
                          pixel_jitter=a.pixel_jitter, focus_photons=a.focus_photons,
                          data_passes=tuple(a.data_passes))


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        settings = settings_from_args(args)
        if args.builtin:
            from .testing.scenes import BUILTIN
            if args.builtin not in BUILTIN:
                raise SceneError(f"unknown built-in scene {args.builtin!r}; choose from {sorted(BUILTIN)}")
            kw = {"resolution": tuple(args.resolution)} if args.resolution else {}
            scene = BUILTIN[args.builtin](**kw)
        else:
            scene = Scene.load(args.scene)
    except (SceneError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    from .imageio import write_exr, write_png
    from .integrator import render

    stats_file = open(args.stats, "w") if args.stats else None
    t0 = time.perf_counter()

    def report(result):
        s = result.stats[-1]
        if stats_file:
            stats_file.write(json.dumps(s) + "\n")
            stats_file.flush()
        if not args.quiet:
            print(f"pass {s['pass']:4d}  {s['elapsed_s']:7.1f} s  visible {s['visible_fraction']:.4g}"
                  f"  acceptance {s['acceptance_rate']:.3f}  theta {s['mutation_size']:.3g}", flush=True)

    try:
        result = render(scene, settings, on_iteration=report)
    except ValueError as e:                 # (e.g. a light group the scene does not have)
        print(f"error: {e}", file=sys.stderr)
        return 2
    finally:
        if stats_file:
            stats_file.close()
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    write_exr(args.output, result.image, result.data)
    if args.png:
        write_png(args.png, result.image)
    if not args.quiet:
        print(f"wrote {args.output} ({result.passes} passes, {time.perf_counter() - t0:.1f} s; "
              f"direct light from {result.direct_light.replace('sampled', 'light samples')})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
