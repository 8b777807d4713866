"""What does a change cost?  The same renders with the core of two git revisions, interleaved.

For each scene, size and method this script renders with the core of ``--base`` (a commit, checked
out with ``git archive`` into a temporary folder) and with the working tree's, each in a fresh
Python process, alternating within every round so that each ratio is taken under the same machine
load; it prints the medians of the render times (the ``render`` call alone: no start-up, no scene
build), their ratio head / base with its range over the rounds, and the two images' means (the
same seeds: a change that moves them has changed the image, not only the time).

    python benchmarks/revision_cost.py --base 98bcc77 [--scenes cornell_box glass_ceiling_room]
        [--sizes 160x120] [--methods ppm amcmcppm] [--passes 4] [--photons 100000] [--rounds 3]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Run in a child process with the revision's folder first on sys.path.
CHILD = """
import json, sys, time
import numpy as np
from core import RenderSettings, render
from core.testing.scenes import BUILTIN
a = json.loads(sys.argv[1])
scene = BUILTIN[a["scene"]](resolution=tuple(a["size"]))
settings = RenderSettings(method=a["method"], passes=a["passes"], photons_per_pass=a["photons"],
                          workers=1, seed=1)
t0 = time.perf_counter()
image = render(scene, settings).image
print(json.dumps({"seconds": time.perf_counter() - t0, "mean": float(image[..., :3].mean()),
                  "finite": bool(np.isfinite(image).all())}))
"""


def checkout(rev, into):
    """The files of ``rev`` (``git archive``) in the folder ``into``."""
    archive = subprocess.run(["git", "-C", ROOT, "archive", "--format=tar", rev], check=True,
                             capture_output=True).stdout
    path = os.path.join(into, "archive.tar")
    with open(path, "wb") as f:
        f.write(archive)
    with tarfile.open(path) as tar:
        tar.extractall(into, filter="data")
    return into


def run(tree, case):
    env = dict(os.environ, PYTHONPATH=tree)
    out = subprocess.run([sys.executable, "-c", CHILD, json.dumps(case)], check=True, capture_output=True,
                         text=True, env=env, cwd=tree).stdout
    result = json.loads(out.strip().splitlines()[-1])
    assert result["finite"], (tree, case)
    return result


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--base", required=True, help="the revision to compare the working tree with")
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "glass_ceiling_room"])
    ap.add_argument("--sizes", nargs="+", default=["160x120"])
    ap.add_argument("--methods", nargs="+", default=["ppm", "amcmcppm"])
    ap.add_argument("--passes", type=int, default=4)
    ap.add_argument("--photons", type=int, default=100_000, help="photons per pass (one worker)")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        base = checkout(args.base, tmp)
        print(f"{args.passes} passes of {args.photons} photons, one worker; head = the working tree, "
              f"base = {args.base}; medians over {args.rounds} rounds")
        print(f"{'scene':20s} {'size':8s} {'method':9s} {'base s':>7s} {'head s':>7s}   "
              f"{'head / base (range)':22s} {'mean base':>10s} {'mean head':>10s}")
        for name in args.scenes:
            for size in args.sizes:
                w, h = (int(v) for v in size.split("x"))
                for method in args.methods:
                    case = {"scene": name, "size": [w, h], "method": method, "passes": args.passes,
                            "photons": args.photons}
                    runs = {"base": [], "head": []}
                    for _ in range(args.rounds):
                        for which, tree in (("base", base), ("head", ROOT)):
                            runs[which].append(run(tree, case))
                    tb = np.array([r["seconds"] for r in runs["base"]])
                    th = np.array([r["seconds"] for r in runs["head"]])
                    ratio = th / tb
                    print(f"{name:20s} {size:8s} {method:9s} {np.median(tb):7.2f} {np.median(th):7.2f}   "
                          f"{np.median(ratio):.3f} ({ratio.min():.3f}-{ratio.max():.3f})        "
                          f"{runs['base'][0]['mean']:10.5f} {runs['head'][0]['mean']:10.5f}", flush=True)


if __name__ == "__main__":
    main()
