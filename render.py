"""Render a .blend file with the AMCMCPPM engine, inside Blender or with the ``bpy`` module.

    blender -b scene.blend -P render.py -- --output out.exr [flags]
    python render.py scene.blend --output out.exr [flags]

Settings flags use the core command line's names (``python -m core render --help``)
and override the .blend's AMCMCPPM settings; settings not given keep the file's
values.  ``--output`` is written by Blender: ``.exr`` as 32-bit float linear RGBA,
``.png``/``.jpg``/``.tif`` through the scene's colour management (view transform,
look, exposure).  ``--stats`` writes the core's per-pass statistics as JSON lines;
``--snapshot-times 1,2,4 --snapshot-dir DIR`` saves the image as EXR at those
elapsed seconds (when neither ``--passes`` nor ``--time-limit`` is given, the
render then runs until the last snapshot time).

Exit status: 0 on success, 1 when the render fails, 2 for bad arguments or an
unreadable file; failures print one line starting with ``render.py: error:``.
The add-on is taken from the installed extension when Blender has it enabled,
otherwise loaded from this script's directory and registered.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time

ENGINE = "AMCMCPPM"
ADDON_MODULE = "amcmcppm"
HERE = os.path.dirname(os.path.abspath(__file__))

FORMATS = {".exr": "OPEN_EXR", ".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".tif": "TIFF",
           ".tiff": "TIFF"}

# Flag -> scene.amcmcppm property, for every setting the panel shows.
SETTING_FLAGS = {
    "method": "method", "passes": "passes", "time_limit": "time_limit", "seed": "seed",
    "target_acceptance": "target_acceptance", "mutation": "mutation", "normalisation": "normalisation",
    "photons_per_pass": "photons_per_pass",
    "first_pass_photons": "first_pass_photons", "workers": "workers", "chains": "chains",
    "initial_radius": "initial_radius_px", "alpha": "alpha", "max_bounces": "max_bounces",
    "initial_mutation_size": "initial_mutation_size", "glossy_through": "glossy_through_roughness",
    "bias_correction": "bias_correction", "edge_coverage": "edge_coverage", "direct_light": "direct_light",
    "direct_samples": "direct_samples", "pixel_jitter": "pixel_jitter", "focus_photons": "focus_photons",
    "diffuse_bounces": "diffuse_bounces", "glossy_bounces": "glossy_bounces",
    "transmission_bounces": "transmission_bounces", "volume_bounces": "volume_bounces",
    "caustics_reflective": "caustics_reflective", "caustics_refractive": "caustics_refractive",
    "transparent_bounces": "transparent_max_bounces",
}


class Failure(Exception):
    """A failure reported as one line with an exit status."""

    def __init__(self, message, status):
        super().__init__(message)
        self.status = status


class ArgumentParser(argparse.ArgumentParser):
    def error(self, message):
        raise Failure(message, 2)


def build_parser():
    p = ArgumentParser(prog="render.py", description="Render a .blend with the AMCMCPPM engine.")
    p.add_argument("blend", nargs="?", help=".blend file (optional inside Blender, where -b opens it)")
    p.add_argument("--output", "-o", required=True,
                   help="image to write: .exr (linear float RGBA) or .png/.jpg/.tif (colour managed)")
    p.add_argument("--png", help="also write a colour-managed PNG")
    g = p.add_argument_group("settings (default: the .blend's values)")
    g.add_argument("--method", choices=("amcmcppm", "ppm", "auto"))
    g.add_argument("--passes", type=int, help="passes (0 = until --time-limit)")
    g.add_argument("--time-limit", type=float, help="seconds (0 = no limit)")
    g.add_argument("--seed", type=int)
    g.add_argument("--target-acceptance", type=float)
    g.add_argument("--mutation", choices=("off", "paper", "exact"))
    g.add_argument("--normalisation", choices=("cumulative", "per_pass"))
    g.add_argument("--photons-per-pass", type=int,
                   help="photon paths per pass and worker (0 = automatic: grows with the image)")
    g.add_argument("--first-pass-photons", type=int,
                   help="photon paths per worker in the first pass, growing 4 times a pass up to "
                        "--photons-per-pass (0 = automatic)")
    g.add_argument("--workers", type=int, help="0 = one per CPU core")
    g.add_argument("--chains", type=int, help="Markov chains per worker (AMCMCPPM)")
    g.add_argument("--initial-radius", type=float, help="initial gather radius in pixel footprints")
    g.add_argument("--alpha", type=float)
    g.add_argument("--direct-light", choices=("photons", "sampled"),
                   help="light straight from emitters from the photons or from light samples")
    g.add_argument("--direct-samples", type=int,
                   help="light samples per pixel and pass (--direct-light sampled)")
    g.add_argument("--pixel-jitter", choices=("stratified", "random"),
                   help="where in its pixel (and on the lens) each pass's camera ray starts, which lobes it "
                        "takes and where its light samples fall (stratified over the passes, or random)")
    g.add_argument("--focus-photons", action=argparse.BooleanOptionalAction, default=None,
                   help="aim uniform photons from the sun and the world at what the camera sees, or "
                        "through the light portals, where that pays (--no-focus-photons: off)")
    g.add_argument("--bias-correction", action=argparse.BooleanOptionalAction, default=None,
                   help="correct the image for the gather radius's blur (--no-bias-correction: off)")
    g.add_argument("--edge-coverage", action=argparse.BooleanOptionalAction, default=None,
                   help="keep gathers near surface edges from darkening (--no-edge-coverage: off)")
    g.add_argument("--max-bounces", type=int, help="most bounces of a light path (Cycles' Total)")
    g.add_argument("--diffuse-bounces", type=int, help="most diffuse bounces (Cycles' Diffuse)")
    g.add_argument("--glossy-bounces", type=int, help="most glossy bounces (Cycles' Glossy)")
    g.add_argument("--transmission-bounces", type=int,
                   help="most transmission bounces (Cycles' Transmission)")
    g.add_argument("--volume-bounces", type=int, help="most scatterings in volumes (Cycles' Volume)")
    g.add_argument("--transparent-bounces", type=int,
                   help="most transparent surfaces a light path crosses (Cycles' Transparent; 1024: "
                        "not counted)")
    g.add_argument("--caustics-reflective", action=argparse.BooleanOptionalAction, default=None,
                   help="light off mirrors, glossy surfaces and glass lights diffuse ones (Cycles' "
                        "Reflective Caustics; --no-caustics-reflective: off)")
    g.add_argument("--caustics-refractive", action=argparse.BooleanOptionalAction, default=None,
                   help="light through glass lights diffuse surfaces (Cycles' Refractive Caustics; "
                        "--no-caustics-refractive: off)")
    g.add_argument("--initial-mutation-size", type=float)
    g.add_argument("--glossy-through", type=float,
                   help="camera paths go on through glossy lobes smoother than this roughness")
    f = p.add_argument_group("frame")
    f.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"), help="resolution before percentage")
    f.add_argument("--resolution-percentage", type=int, metavar="P")
    f.add_argument("--border", type=float, nargs=4, metavar=("XMIN", "XMAX", "YMIN", "YMAX"),
                   help="render only this part of the frame (fractions, y from the bottom)")
    f.add_argument("--frame", type=int, help="frame number to render")
    o = p.add_argument_group("statistics")
    o.add_argument("--stats", help="write per-pass statistics as JSON lines to this file")
    o.add_argument("--snapshot-times", help="comma-separated elapsed seconds, e.g. 1,2,4,8")
    o.add_argument("--snapshot-dir", help="folder for the snapshot EXRs (with --snapshot-times)")
    o.add_argument("--quiet", "-q", action="store_true", help="print nothing on success")
    return p


def script_argv(bpy):
    """Arguments meant for this script: after ``--`` inside Blender, all of them with the module."""
    if "--" in sys.argv:
        return sys.argv[sys.argv.index("--") + 1:]
    return [] if bpy.app.binary_path else sys.argv[1:]


def ensure_addon(bpy):
    """Make the AMCMCPPM engine available; register the add-on from this directory if needed."""
    scene = bpy.context.scene
    old = scene.render.engine
    try:
        scene.render.engine = ENGINE
        scene.render.engine = old
        return
    except TypeError:
        pass
    if ADDON_MODULE not in sys.modules:
        spec = importlib.util.spec_from_file_location(ADDON_MODULE, os.path.join(HERE, "__init__.py"),
                                                      submodule_search_locations=[HERE])
        module = importlib.util.module_from_spec(spec)
        sys.modules[ADDON_MODULE] = module
        spec.loader.exec_module(module)
    sys.modules[ADDON_MODULE].register()


def configure(bpy, scene, args):
    """Apply the flags to ``scene``; raise Failure(..., 2) for values Blender rejects.  A bounce or
    caustics flag switches a file that takes Cycles' Light Paths to the engine's own, set to Cycles'
    first (so the settings not given stay as they were)."""
    props = scene.amcmcppm
    names = props.light_path_limits()[0]
    light_paths = [flag for flag, prop in SETTING_FLAGS.items() if prop in names]
    if props.light_paths_from_cycles and any(getattr(args, flag) is not None for flag in light_paths):
        props.own_light_paths()
    for flag, prop in SETTING_FLAGS.items():
        value = getattr(args, flag)
        if value is not None:
            try:
                setattr(props, prop, value)
            except (TypeError, ValueError) as e:
                raise Failure(f"--{flag.replace('_', '-')}: {e}", 2) from None
            stored = getattr(props, prop)
            close = isinstance(value, float) and abs(stored - value) <= 1e-6 * max(1.0, abs(value))
            if stored != value and not close:
                raise Failure(f"--{flag.replace('_', '-')} {value} is outside the allowed range "
                              f"(Blender clamped it to {stored:g})", 2)
    if args.snapshot_times:
        props.snapshot_times = args.snapshot_times
        props.snapshot_dir = os.path.abspath(args.snapshot_dir or "snapshots")
        try:
            times = [float(t) for t in args.snapshot_times.replace(";", ",").split(",") if t.strip()]
        except ValueError:
            raise Failure(f"--snapshot-times {args.snapshot_times!r}: expected numbers such as 1,2,4", 2) \
                from None
        if not times or min(times) <= 0:
            raise Failure(f"--snapshot-times {args.snapshot_times!r}: expected positive seconds", 2)
        if args.passes is None and args.time_limit is None:
            props.passes, props.time_limit = 0, max(times)
    if args.stats:
        path = os.path.abspath(args.stats)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        open(path, "w").close()             # the engine appends; start from an empty file
        props.stats_path = path
    r = scene.render
    if args.resolution:
        r.resolution_x, r.resolution_y = args.resolution
    if args.resolution_percentage is not None:
        r.resolution_percentage = args.resolution_percentage
    if args.border:
        r.use_border = True
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = args.border
    if args.frame is not None:
        scene.frame_set(args.frame)
    if r.use_multiview:
        # (--output is one image: Blender would write its name with each view's suffix instead)
        r.use_multiview = False
        print("render.py: Stereoscopy turned off: --output is one image, the camera's own view (in "
              "Blender, or with blender -b FILE -f N, each eye renders into its own image)")
    set_output(scene, args.output)


def set_output(scene, path):
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise Failure(f"--output {path}: unknown image type {ext!r}; use one of {', '.join(FORMATS)}", 2)
    r = scene.render
    r.filepath = os.path.abspath(path)
    r.use_file_extension = False
    s = r.image_settings
    if hasattr(s, "media_type"):        # Blender 5.0 (multilayer EXR is a media type there)
        s.media_type = "IMAGE"
    s.file_format = FORMATS[ext]
    if ext == ".exr":
        s.color_mode = "RGBA"
        s.color_depth = "32"
        s.exr_codec = "ZIP"
    else:
        s.color_mode = "RGBA" if ext in (".png", ".tif", ".tiff") else "RGB"
        s.color_depth = "8"
        s.color_management = "FOLLOW_SCENE"
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)


def run(argv):
    import bpy

    args = build_parser().parse_args(script_argv(bpy) if argv is None else argv)
    # Before opening the file, so that Blender finds the engine the file selects.
    ensure_addon(bpy)
    if args.blend:
        if not os.path.isfile(args.blend):
            raise Failure(f"no such .blend file: {args.blend}", 2)
        try:
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
        except RuntimeError as e:
            raise Failure(f"cannot open {args.blend}: {str(e).strip().splitlines()[-1]}", 2) from None
    elif not bpy.app.binary_path:
        raise Failure("a .blend file is required", 2)
    scene = bpy.context.scene
    if scene.camera is None:
        raise Failure(f"scene '{scene.name}' has no camera", 2)
    scene.render.engine = ENGINE
    configure(bpy, scene, args)
    t0 = time.perf_counter()
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as e:
        raise Failure(" ".join(str(e).split()).removeprefix("Error: "), 1) from None
    if not os.path.isfile(scene.render.filepath):
        raise Failure(f"the render finished but {scene.render.filepath} was not written", 1)
    if args.png:
        write_png(bpy, scene, args.png)
    if not args.quiet:
        extra = f" and {args.png}" if args.png else ""
        print(f"render.py: wrote {args.output}{extra} ({time.perf_counter() - t0:.1f} s)")
    return 0


def write_png(bpy, scene, path):
    image = bpy.data.images.get("Render Result")
    if image is None:
        raise Failure("no render result to save as PNG", 1)
    set_output(scene, path)
    image.save_render(filepath=os.path.abspath(path), scene=scene)


def main(argv=None):
    try:
        return run(argv)
    except Failure as e:
        print(f"render.py: error: {e}", file=sys.stderr)
        return e.status
    except Exception as e:      # Blender's -P would otherwise exit 0 after an uncaught exception
        print(f"render.py: error: {type(e).__name__}: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
