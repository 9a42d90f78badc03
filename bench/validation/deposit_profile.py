#!/usr/bin/python3
"""The planar granular collapse's final deposit across dx: run-out of the
farthest particle, where the deposit thinner than a threshold begins, and
the deposit's height along the floor, with and without solver keys.

Usage: deposit_profile.py --aspects 1 --dx-factors 1,0.5,0.25
       [--solver '{"contact_gap_fixed": false}'] [--work DIR] [--threads N]

Each run's cache is kept in the work folder (every frame's PLY), and a run
whose cache is there is measured again without being run. Heights are in
L0 (the column's length), at x measured from the column's first front;
the height at x is the top of the particles within a quarter cell of it,
plus half a particle spacing."""
import argparse
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import experiments as E  # noqa: E402
import validate as V  # noqa: E402

THRESHOLDS = (0.005, 0.01)  # m: where the deposit thinner than these begins
STATIONS = (0.0, 0.4, 0.8, 1.2, 1.6)  # x past the first front, in L0


def measure(scene, out):
    n = scene["frames"]["count"]
    p0, pn = V.read_ply(V.ply_path(out, 0)), V.read_ply(V.ply_path(out, n))
    col = V.box_of(scene, "column")
    L0 = col["max"][0] - col["min"][0]
    floor = col["min"][1]
    dx = scene["domain"]["dx"]
    front0 = p0["x"].max() + 0.25 * dx
    x, top = pn["x"], pn["y"] - floor + 0.25 * dx

    def height(at):
        near = np.abs(x - at) < 0.25 * dx + 1e-9
        return float(top[near].max()) if near.any() else 0.0

    # The validation's own run-out: the farthest particle.
    r = {"runout": V.measure_granular(scene, out)[1]}
    # The deposit from the back wall on, in bins of a particle spacing:
    # the first bin lower than the threshold ends it.
    w = 0.5 * dx
    bins = np.zeros(int(math.ceil(x.max() / w)) + 2)
    np.maximum.at(bins, (x / w).astype(int), top)
    for t in THRESHOLDS:
        low = np.nonzero(bins < t)[0]
        end = (low[0] if len(low) else len(bins)) * w
        r["thicker than %g mm ends" % (1000 * t)] = (end - front0) / L0
    r["heights"] = [height(front0 + s * L0) / L0 for s in STATIONS]
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--aspects", default="1")
    ap.add_argument("--dx-factors", default="1,0.5,0.25")
    ap.add_argument("--solver", default="{}")
    ap.add_argument("--work", default=os.path.join(V.ROOT, "build", "validation", "deposit"))
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    extra = json.loads(args.solver)
    tag = "-".join("%s=%s" % kv for kv in sorted(extra.items())) or "default"
    print("heights at x/L0 = %s past the first front" % ", ".join("%g" % s for s in STATIONS))
    for a in (float(v) for v in args.aspects.split(",")):
        for f in (float(v) for v in args.dx_factors.split(",")):
            s = E.planar_scene(a, f)
            s["solver"].update(extra)
            work = os.path.join(args.work, "a%g_dx%g_%s" % (a, f, tag))
            os.makedirs(work, exist_ok=True)
            path, out = os.path.join(work, "scene.json"), os.path.join(work, "cache")
            with open(path, "w") as fh:
                json.dump(s, fh, indent=1)
            if not os.path.exists(os.path.join(out, "run.json")):
                V.run_triad(path, out, args.threads)
            r = measure(s, out)
            print("a=%g dx=%g %s: run-out %.2f; %s; heights %s" % (
                a, s["domain"]["dx"], tag, r["runout"],
                "; ".join("%s %.3f" % (k, v) for k, v in r.items() if k.startswith("thicker")),
                " ".join("%.3f" % h for h in r["heights"])), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
