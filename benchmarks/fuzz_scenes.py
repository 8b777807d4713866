"""Robustness fuzz sweep of the Blender add-on: random scenes rendered, each in its own process.

Every case builds a random scene with ``bpy`` (``fuzz_scene_gen.py``: meshes good and degenerate,
curves, text, metaballs, collection instances, geometry nodes, point clouds, hair, particles,
volumes, random node trees of the shader, texture and utility nodes, lights and worlds of every
kind, cameras, view-layer passes, object flags; and, from case 3000 on, shape keys and keyframes
at another frame, drivers, stereo views, cameras inside closed objects, nested glass and volumes,
linked duplicates, instancing by vertices and faces, scenes scaled by 1e-4 to 1e4, light and shadow
linking, beveled curves, Grease Pencil, odd material structures, nested node groups, a Principled
BSDF of every input textured, Light Path tricks and AOV outputs; ordinary values with a share of
extreme ones) and
random engine settings and image size (1 x 1 to 48 x 36 pixels, 1 to 3 passes, one worker), renders
it with our engine in a subprocess with a time limit (``bpy.ops.render.render``; one case in ten of
the ``combo`` phase saves the .blend and renders it with ``python render.py`` instead) and
records what happened:

    ok                an image, every value finite
    render_error      the render failed with an error (a scene the engine refuses, or a bug)
    nonfinite         an image with NaN or infinite values
    no_image          the render returned without writing the image (or, with multiview, a
                      view's image is all 0: never rendered)
    timeout           killed after ``--timeout`` seconds
    crash             the process ended without a result (a signal, a hard exit)
    driver_exception  this script failed inside the case process

with a signature to group the failures by: the first traceback the process printed (its
exception and the last repository frame), else the outcome and error.  A case's id is its seed:
``run --start S --count N`` makes cases S .. S + N - 1, the same ones on every machine.  Phases:
``combo`` (the base scene, floor, camera and point light, each kept with chance 0.9, plus one to
seven features drawn by ``WEIGHTS``, and from case ``NEW_FEATURES_FROM`` on none to three drawn by
``NEW_WEIGHTS``; random settings) and ``single`` (the base scene plus one feature, each in turn by
id: 0 .. 20 those of ``WEIGHTS``, 21 .. 36 those of ``NEW_WEIGHTS``; few random settings).

    python benchmarks/fuzz_scenes.py run --start 1000 --count 300
    python benchmarks/fuzz_scenes.py run --phase single --start 0 --count 37
    python benchmarks/fuzz_scenes.py replay 1234          # rerun a case, print what it built and did
    python benchmarks/fuzz_scenes.py reduce 1234          # drop features while the failure stays
    python benchmarks/fuzz_scenes.py run --count 2 --resolution 8 6     # smoke run (seconds)

writes ``benchmarks/results/fuzz_scenes/``: results.jsonl (one line a case run: its spec, outcome,
signature, settings and image statistics), logs/<id>.out, .err and .json (the case process's
output and result, with the log of what each feature built), img/<id>.exr, blend/<id>.blend
(render.py cases and ``replay --save-blend``) and reduced/<id>.json (``reduce``'s smallest case,
which ``replay`` takes as a file).  ``run`` ends with a summary: cases run, counts per outcome,
the errors' first lines.
"""
from __future__ import annotations

import argparse
import collections
import importlib.util
import json
import os
import random
import re
import signal
import subprocess
import sys
import time
import traceback

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "amcmcppm"
BASE_FEATURES = ("floor", "camera", "light")
# How often each feature of fuzz_scene_gen.FEATURES beyond the base scene is drawn (combo phase); in
# this order the single phase takes them by id.  (Here, so that this process needs no bpy.)
WEIGHTS = {"mesh": 6, "degenerate": 3, "ops_primitive": 2, "text": 1, "curve": 1.5, "metaball": 1,
           "collection_instance": 1.5, "gn": 2, "point_cloud": 1, "hair_curves": 1, "particles": 1,
           "volume_object": 0.5, "volume_cube": 1.5, "flags": 2, "random_light": 4, "world": 3,
           "camera_random": 2.5, "view_layer": 1.5, "material_ball": 5, "emissive_mesh": 1,
           "render_opts": 1.5}
# Features added in stop 75: the single phase takes them by id after those above (ids 21 on); a
# combo case from NEW_FEATURES_FROM on also draws none to three of them from a generator of its
# own, so that every case before it (and each of its draws above) stays as it was.
NEW_WEIGHTS = {"animated": 1.5, "drivers": 1, "stereo": 0.7, "camera_enclosed": 1, "nested_glass": 1.5,
               "linked_duplicates": 1.5, "dupli_verts_faces": 1, "scene_scale": 1, "light_linking": 1.5,
               "curve_bevel": 1, "grease_pencil": 0.5, "material_odd": 1.5, "node_groups": 1.5,
               "principled_all": 1.5, "light_path": 1.5, "aov_outputs": 1}
NEW_FEATURES_FROM = 3000
# Features acting on what the others made: drawn features put these last (scene_scale after the
# others, light_linking before it).
LATE_FEATURES = ("flags", "camera_random", "view_layer", "render_opts", "light_linking", "scene_scale")
TRACEBACK_FRAME = re.compile(r'File "([^"]+)", line (\d+), in (\S+)')


# ------------------------------------------------------------------------------ the case process
def load_addon():
    """Register the repository as the add-on package ``amcmcppm`` (as tests/addon/conftest.py)."""
    spec = importlib.util.spec_from_file_location(PACKAGE, os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = module
    spec.loader.exec_module(module)
    module.register()


def read_exr_channels(path):
    """Every channel of every part of the EXR at ``path``: {"part:channel": (H, W) float32}."""
    import OpenEXR
    channels = {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            for name, channel in part.channels.items():
                channels[f"{part.name()}:{name}"] = np.asarray(channel.pixels, np.float32)
    return channels


def image_stats(path):
    """Channel count, non-finite and negative value counts, shape, mean and max of the colour."""
    channels = read_exr_channels(path)
    info = {"channels": len(channels), "nonfinite": {}, "negative": {}}
    for name, a in channels.items():
        bad = int((~np.isfinite(a)).sum())
        if bad:
            info["nonfinite"][name] = bad
        if "Combined" in name or name in (":R", ":G", ":B"):
            negative = int((a < 0).sum())
            if negative:
                info["negative"][name] = negative
        if name.endswith("R") and "shape" not in info:
            info["shape"] = list(a.shape)
    colour = [a for n, a in channels.items() if n.endswith(("R", "G", "B"))
              and ("Combined" in n or n.startswith(":"))]
    if colour:
        c = np.stack(colour)
        finite = np.isfinite(c)
        info["mean"] = float(c[finite].mean()) if finite.any() else None
        info["max"] = float(c[finite].max()) if finite.any() else None
    return info


def view_images(scene, exr):
    """[(view suffix, path)] of the images the render wrote: ``exr`` itself, or with multiview
    (Individual views) one file a view, Blender's suffix (``_L``) before the extension."""
    if os.path.exists(exr):
        return [("", exr)]
    if not scene.render.use_multiview:
        return []
    root, ext = os.path.splitext(exr)
    views = [v for v in scene.render.views if v.use] if scene.render.views_format == "MULTIVIEW" else \
        [v for v in scene.render.views if v.name in ("left", "right") and v.use]
    return [(v.file_suffix, root + v.file_suffix + ext) for v in views
            if os.path.exists(root + v.file_suffix + ext)]


def exr_readable(path):
    """Whether the EXR at ``path`` opens."""
    try:
        read_exr_channels(path)
    except Exception:
        return False
    return True


def image_is_zero(path):
    """Whether every value of every channel of the EXR at ``path`` is 0 (a view never rendered)."""
    return all(not np.any(a) for a in read_exr_channels(path).values())


def render(spec, scene, out, timeout):
    """Render ``scene`` into out/img/<id>.exr as ``spec["mode"]`` says; the error text or None."""
    import bpy
    exr = os.path.join(out, "img", f"{spec['id']}.exr")
    blend = os.path.join(out, "blend", f"{spec['id']}.blend")
    if spec.get("save_blend") or spec["mode"] == "renderpy":
        bpy.ops.wm.save_as_mainfile(filepath=blend)
    if spec["mode"] == "renderpy":
        p = subprocess.run([sys.executable, os.path.join(ROOT, "render.py"), blend, "--output", exr,
                            "--workers", "1"], capture_output=True, text=True, timeout=timeout - 10)
        print(p.stdout)
        print(p.stderr, file=sys.stderr)
        if p.returncode == 0:
            return None
        lines = (p.stdout + p.stderr).strip().splitlines()       # (its last: "render.py: error: ...")
        return lines[-1] if lines else f"render.py exit status {p.returncode}"
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as e:
        return str(e).strip()
    return None


def run_case(payload):
    """Build and render one case (in this process) and write its result to logs/<id>.json."""
    spec, out = payload["spec"], payload["out"]
    t0 = time.time()
    res = {"id": spec["id"], "spec": spec, "status": None}
    try:
        load_addon()
        import fuzz_scene_gen as gen
        scene, case, res["settings"], res["feature_failures"] = gen.build_case(
            spec["features"], spec["settings_seed"], spec.get("light_settings", False),
            spec.get("resolution"))
        res["log"] = case.log_lines
        s = scene.render.image_settings
        s.media_type = "MULTI_LAYER_IMAGE" if case.passes else "IMAGE"
        s.file_format = "OPEN_EXR_MULTILAYER" if case.passes else "OPEN_EXR"
        s.color_mode = "RGBA"
        s.color_depth = "32"
        exr = os.path.join(out, "img", f"{spec['id']}.exr")
        if os.path.exists(exr):
            os.remove(exr)
        scene.render.filepath = exr
        scene.render.use_file_extension = False
        t1 = time.time()
        res["build_s"] = round(t1 - t0, 2)
        error = render(spec, scene, out, payload["timeout"])
        res["render_s"] = round(time.time() - t1, 2)
        if error is not None:
            res["status"], res["error"] = "render_error", error
        views = view_images(scene, exr)
        unreadable = [path for _, path in views if not exr_readable(path)]
        if unreadable:          # (Blender's EXR writer can fail and leave an empty file)
            views = []
            if res["status"] is None:
                res["status"], res["error"] = "no_image", f"unreadable image {unreadable[0]}"
        if views:
            res["image"] = image_stats(views[0][1])
            if len(views) > 1 or views[0][0]:
                res["views"] = {suffix: image_stats(path) for suffix, path in views}
                for info in res["views"].values():
                    res["image"]["nonfinite"].update(info["nonfinite"])
            empty = [suffix for suffix, path in views if image_is_zero(path)] if len(views) > 1 else []
            if res["status"] is None and empty:
                res["status"], res["error"] = "no_image", f"view {', '.join(empty)} empty (every value 0)"
            if res["status"] is None:
                res["status"] = "nonfinite" if res["image"]["nonfinite"] else "ok"
        elif res["status"] is None:
            res["status"] = "no_image"
    except Exception:
        res["status"] = "driver_exception"
        res["error"] = traceback.format_exc()
    res["total_s"] = round(time.time() - t0, 2)
    with open(os.path.join(out, "logs", f"{spec['id']}.json"), "w") as f:
        json.dump(res, f, default=str)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)         # (at once: the result is written; nothing at Blender's exit may change it)


# ------------------------------------------------------------------------------ the parent
def make_spec(case_id, phase, resolution=None):
    """The case ``case_id`` of ``phase``, drawn from random.Random(case_id)."""
    r = random.Random(case_id)
    if phase == "single":
        names = list(WEIGHTS) + list(NEW_WEIGHTS)
        features = [[n, r.randint(0, 10 ** 9)] for n in (*BASE_FEATURES, names[case_id % len(names)])]
        spec = {"id": case_id, "features": features, "settings_seed": r.randint(0, 10 ** 9),
                "light_settings": True, "mode": "ops"}
    else:
        extra = r.choices(list(WEIGHTS), weights=list(WEIGHTS.values()), k=r.randint(1, 7))
        base = [n for n in BASE_FEATURES if r.random() < 0.9]
        extra.sort(key=lambda n: n in LATE_FEATURES)
        features = [[n, r.randint(0, 10 ** 9)] for n in base + extra]
        spec = {"id": case_id, "features": features, "settings_seed": r.randint(0, 10 ** 9),
                "mode": "renderpy" if r.random() < 0.1 else "ops"}
        if case_id >= NEW_FEATURES_FROM:
            r2 = random.Random(f"new features {case_id}")
            new = r2.choices(list(NEW_WEIGHTS), weights=list(NEW_WEIGHTS.values()),
                             k=r2.choice([0, 1, 1, 2, 3]))
            features += [[n, r2.randint(0, 10 ** 9)] for n in new]
            features.sort(key=lambda f: (f[0] in LATE_FEATURES) + (f[0] == "scene_scale"))
    if resolution:
        spec["resolution"] = list(resolution)
    return spec


def tracebacks(err):
    """Each traceback in ``err``: its exception line and the last frame in the repository."""
    found = []
    for block in re.split(r"Traceback \(most recent call last\):", err)[1:]:
        lines = block.strip().splitlines()
        frames = [f"{os.path.relpath(f, ROOT)}:{line} {fn}" for f, line, fn in TRACEBACK_FRAME.findall(block)
                  if f.startswith(ROOT) and "/.venv/" not in f]
        exc = next((x for x in lines if re.match(r"^[\w.]+(Error|Exception|Warning)\b", x)),
                   lines[-1] if lines else "")
        found.append({"exc": exc[:300], "where": frames[-1] if frames else None})
    return found


def signature(summary):
    """What to group a failure by (None for a clean case)."""
    status, tbs = summary["status"], summary["tracebacks"]
    if status == "timeout":
        return "timeout"
    if status == "crash":
        return f"crash (exit status {summary['rc']})"
    if tbs:
        exc, where = tbs[0]["exc"], tbs[0]["where"]
        return f"SceneError: {exc[:80]}" if "SceneError" in exc else f"{exc.split(':')[0]} @ {where}"
    if status == "nonfinite":
        return "nonfinite " + ",".join(sorted(summary["image"]["nonfinite"]))
    if status != "ok":
        return f"{status}: {str(summary.get('error'))[:100]}"
    return None


def classify(spec, out, rc, stdout, stderr, timed_out, elapsed):
    """The case's summary from its process's exit, output and result file."""
    path = os.path.join(out, "logs", f"{spec['id']}.json")
    res = {}
    if os.path.exists(path):
        with open(path) as f:
            res = json.load(f)
    if timed_out:
        status = "timeout"
    elif rc != 0 or not res:
        status = "crash"
    else:
        status = res["status"]
    summary = {"id": spec["id"], "features": [n for n, _ in spec["features"]], "rc": rc,
               "elapsed": round(elapsed, 1), "mode": spec["mode"], "status": status,
               "error": res.get("error"), "image": res.get("image"), "settings": res.get("settings"),
               "feature_failures": res.get("feature_failures"), "tracebacks": tracebacks(stderr),
               "warnings": sorted({x.strip() for x in (stdout + "\n" + stderr).splitlines()
                                   if x.startswith(("Warning:", "Error:"))})}
    summary["signature"] = signature(summary)
    return summary


def run_one(spec, out, timeout):
    """Run ``spec`` in a new process (killed with its children after ``timeout`` s); its summary."""
    for sub in ("logs", "img", "blend"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)
    result = os.path.join(out, "logs", f"{spec['id']}.json")
    if os.path.exists(result):
        os.remove(result)
    payload = json.dumps({"spec": spec, "out": out, "timeout": timeout})
    t0 = time.time()
    p = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--child", payload], cwd=out,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    timed_out = False
    try:
        stdout, stderr = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        os.killpg(p.pid, signal.SIGKILL)
        stdout, stderr = p.communicate()
    elapsed = time.time() - t0
    for ext, text in ((".out", stdout), (".err", stderr)):
        with open(os.path.join(out, "logs", f"{spec['id']}{ext}"), "w") as f:
            f.write(text)
    return classify(spec, out, p.returncode, stdout, stderr, timed_out, elapsed)


def headline(summary):
    """An error's first line (a traceback's last: its exception)."""
    lines = str(summary["error"]).strip().splitlines() or [""]
    return lines[-1] if summary["status"] == "driver_exception" else lines[0]


def print_summary(summaries, out, seconds):
    """Cases run, counts per outcome (errors by their headline), the signatures, where the logs are."""
    print(f"\n{len(summaries)} cases run in {seconds:.0f} s")
    counts = collections.Counter(s["status"] for s in summaries)
    for status, n in counts.most_common():
        print(f"  {status:16} {n}")
        if status in ("render_error", "driver_exception", "no_image"):
            lines = collections.defaultdict(list)
            for s in summaries:
                if s["status"] == status:
                    lines[headline(s)].append(s["id"])
            for line, ids in sorted(lines.items(), key=lambda kv: -len(kv[1])):
                print(f"    {len(ids):4} x {line[:120]}  (e.g. {ids[0]})")
    signatures = collections.Counter(s["signature"] for s in summaries if s["signature"])
    if signatures:
        print("  signatures:")
        for sig, n in signatures.most_common():
            print(f"    {n:4} x {sig[:140]}")
    print(f"results: {os.path.join(out, 'results.jsonl')}")
    print(f"logs:    {os.path.join(out, 'logs')}/<id>.out, .err, .json; images: {os.path.join(out, 'img')}")


def case_line(s):
    line = f"{s['id']!s:>6} {s['status']:16} {s['elapsed']:6.1f}s {','.join(s['features'])[:70]:70} "
    return (line + (s["signature"] or ""))[:250]


def command_run(args):
    t0 = time.time()
    summaries = []
    with open(os.path.join(args.out, "results.jsonl"), "a") as log:
        for case_id in range(args.start, args.start + args.count):
            if args.deadline and time.time() - t0 > args.deadline:
                print("deadline reached", flush=True)
                break
            spec = make_spec(case_id, args.phase, args.resolution)
            s = run_one(spec, args.out, args.timeout)
            s["spec"] = spec
            log.write(json.dumps(s, default=str) + "\n")
            log.flush()
            summaries.append(s)
            print(case_line(s), flush=True)
    print_summary(summaries, args.out, time.time() - t0)


def recorded(out, case_id):
    """The summary of the last run of ``case_id`` in out/results.jsonl (None if not there)."""
    path = os.path.join(out, "results.jsonl")
    found = None
    if os.path.exists(path):
        with open(path) as f:
            for line in f:
                record = json.loads(line)
                if record["id"] == case_id:
                    found = record
    return found


def command_replay(args):
    if os.path.isfile(args.case):
        with open(args.case) as f:
            spec = json.load(f)
    else:
        case_id = int(args.case)
        record = recorded(args.out, case_id)
        spec = record["spec"] if record else make_spec(case_id, args.phase, args.resolution)
    if args.save_blend:
        spec["save_blend"] = True
    s = run_one(spec, args.out, args.timeout)
    path = os.path.join(args.out, "logs", f"{spec['id']}.json")
    if os.path.exists(path):
        with open(path) as f:
            print("\n".join(json.load(f).get("log", [])))
    print(json.dumps(s, indent=1, default=str))
    print(f"logs: {os.path.join(args.out, 'logs', str(spec['id']))}.out, .err")


def command_reduce(args):
    record = recorded(args.out, args.case)
    if record is None:
        sys.exit(f"case {args.case} is not in {os.path.join(args.out, 'results.jsonl')}: run it first")
    spec = record["spec"]
    want = args.target or record["signature"]
    if not want:
        sys.exit(f"case {args.case} did not fail: nothing to reduce")
    print("target:", want, flush=True)
    trials = 0

    def fails(features):
        nonlocal trials
        trials += 1
        s = run_one(dict(spec, features=features, id=f"{args.case}-r{trials}"), args.out, args.timeout)
        same = want in str(s["signature"]) or want in str(s["error"])
        print(f"  {'fails' if same else 'passes':6} {','.join(n for n, _ in features)}  {s['signature']}",
              flush=True)
        return same

    features = list(spec["features"])
    i = 0
    while i < len(features):
        trial = features[:i] + features[i + 1:]
        if fails(trial):
            features = trial
        else:
            i += 1
    os.makedirs(os.path.join(args.out, "reduced"), exist_ok=True)
    path = os.path.join(args.out, "reduced", f"{args.case}.json")
    with open(path, "w") as f:
        json.dump(dict(spec, features=features, id=f"{args.case}-min"), f, indent=1)
    print(f"smallest: {','.join(n for n, _ in features)}  ({trials} trials)\n"
          f"rerun:    python {os.path.relpath(__file__, ROOT)} replay {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--out", default=os.path.join(ROOT, "benchmarks", "results", "fuzz_scenes"),
                        help="folder for results.jsonl, logs/, img/ (default: %(default)s)")
    common.add_argument("--timeout", type=float, default=120.0, help="seconds a case may take")
    sub = ap.add_subparsers(dest="command")
    run = sub.add_parser("run", parents=[common], help="run cases start .. start + count - 1")
    run.add_argument("--phase", choices=("combo", "single"), default="combo")
    run.add_argument("--start", type=int, default=0, help="first case id (its seed)")
    run.add_argument("--count", type=int, default=10, help="cases to run")
    run.add_argument("--deadline", type=float, default=0.0, help="start no case after this many seconds")
    run.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"),
                     help="image size of every case (default: each case's random one)")
    replay = sub.add_parser("replay", parents=[common], help="rerun one case and print what it did")
    replay.add_argument("case", help="case id (its recorded spec, else made anew) or a spec .json file")
    replay.add_argument("--phase", choices=("combo", "single"), default="combo",
                        help="for a case id not recorded")
    replay.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"),
                        help="for a case id not recorded")
    replay.add_argument("--save-blend", action="store_true", help="also save the scene in blend/<id>.blend")
    reduce = sub.add_parser("reduce", parents=[common],
                            help="drop a recorded case's features one by one while its failure stays")
    reduce.add_argument("case", type=int)
    reduce.add_argument("--target", help="text the signature or error must contain "
                                         "(default: the case's signature when rerun)")
    args = ap.parse_args()
    if args.child:
        run_case(json.loads(args.child))
    if not args.command:
        ap.error("a command is needed: run, replay or reduce")
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    {"run": command_run, "replay": command_replay, "reduce": command_reduce}[args.command](args)


if __name__ == "__main__":
    main()
