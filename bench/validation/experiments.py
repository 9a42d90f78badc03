#!/usr/bin/python3
"""The experiments across their parameter (issue 17): the granular collapse
at several aspect ratios, planar (Lube et al. 2005) and axisymmetric (Lube
et al. 2004, Lajeunesse et al. 2004), each at two dx, and the dam-break
front at every dx of the sweep against Martin & Moyce and Koshizuka & Oka.

Usage (from the repository root; bench/validation/run.sh runs it after the
sweep):
  /usr/bin/python3 bench/validation/experiments.py [--quick] [--threads N]
      [--only collapse,axisymmetric,dam_break] [--results DIR]
      [--aspects 3,6] [--dx-factors 1,0.5] [--grain-diameter D]
      [--channel-width W [--wall-friction MU]] [--solver JSON]

--quick           the base dx only (no refinement), for a smoke test
--aspects         the planar aspect ratios to run (default 0.5,1,2,3,6)
--dx-factors      factors of the scenes' dx for the collapses (default 1,0.5)
--grain-diameter  the sand's grain_diameter (m): the rate-dependent friction
                  mu(I) (default 0: a constant friction)
--channel-width   planar collapses between frictional side walls W apart
                  (m), as in the experiments' channel; half of it is
                  simulated, the domain's frictionless wall at z = 0 being
                  the channel's plane of symmetry (default: none, the slab
                  4 cells thick between frictionless walls, an infinitely
                  wide channel)
--wall-friction   the side walls' Coulomb coefficient against the sand
                  (default 0.4, sand on acrylic or glass)
--solver          solver keys (a JSON object) added to every collapse's
                  scene, e.g. '{"contact_gap_fixed": true}'

Writes, under the results directory: collapse_aspect.csv and .png (run-out
and final height against a, per geometry and dx, with the fitted laws),
dam_break_front.csv and .png (the front Z against T at each dx, with both
experiments), and experiments.md (the tables bench/RESULTS.md quotes).
"""
import argparse
import csv
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import validate as V  # noqa: E402

PLANAR_A = [0.5, 1, 2, 3, 6]
AXISYMMETRIC_A = [0.5, 1, 2, 3]
COLLAPSE_DX = [1, 0.5]  # factors of the scenes' dx
SOLVER_EXTRA = {}  # --solver: keys added to every collapse's scene
DAM_BREAK_DX = [2, 1, 0.5, 0.25]


def snap(x, dx):
    return round(x / dx) * dx


def collapse_duration(a):
    # The tallest columns fall for sqrt(2 h / g) before they spread; every
    # run here has stopped a few frames before its end (measured).
    return 1.0 + 0.25 * math.sqrt(a)


def planar_scene(a, f, channel=None, grain=0.0):
    """The planar case's scene at aspect ratio a and dx factor f: a column
    L0 x H0 whose smaller side is 0.1 m (10 cells at the scene's dx), against
    the back wall, in a domain long enough for 1.6 times Lube's run-out.
    With channel = (W, mu_w), the column fills half a channel W wide, beside
    a fixed side wall of friction mu_w; with grain > 0 the sand's friction
    follows mu(I) for grains of that diameter."""
    s = V.load_scene("granular_collapse")
    dx = s["domain"]["dx"] * f
    floor = V.box_of(s, "floor")["max"][1]
    L0 = max(0.1, 0.1 / a)
    H0 = a * L0
    longest = V.law_bracket(V.PLANAR_FITS, "runout", a)[1]
    X = snap(L0 * (1 + 1.6 * longest) + 0.1, dx)
    Y = snap(floor + H0 + 0.06, dx)
    s["domain"].update(dx=dx, max=[X, Y, 4 * dx])
    s["objects"][V.object_index(s, "column")]["shape"]["box"] = {
        "min": [0, floor, 0], "max": [L0, floor + H0, 4 * dx]}
    s["objects"][V.object_index(s, "floor")]["shape"]["box"] = {
        "min": [0, 0, 0], "max": [X, floor, 4 * dx]}
    s["frames"] = {"count": int(round(collapse_duration(a) * 25)), "fps": 25}
    if grain > 0:
        s["materials"]["sand"]["grain_diameter"] = grain
    if channel:
        # The channel's half from its plane of symmetry (z = 0) to the side
        # wall, a fixed box three cells thick along the whole domain.
        half, mu_w = 0.5 * channel[0], channel[1]
        Z = half + 3 * dx
        s["domain"]["max"][2] = Z
        s["objects"][V.object_index(s, "column")]["shape"]["box"]["max"][2] = half
        s["objects"][V.object_index(s, "floor")]["shape"]["box"]["max"][2] = Z
        s["objects"].append({"name": "side_wall", "kind": "rigid", "density": 1000,
                             "fixed": True, "friction": mu_w,
                             "shape": {"box": {"min": [0, 0, half], "max": [X, Y, Z]}}})
    return s


def cylinder_obj(path, height, sides=96):
    """A closed cylinder of radius 1 and the given height, base at y = 0."""
    lines = ["# cylinder of radius 1 and height %g, base at y = 0 (%d sides)" % (height, sides)]
    for k in range(sides):
        t = 2 * math.pi * k / sides
        lines += ["v %.6f 0 %.6f" % (math.cos(t), math.sin(t)),
                  "v %.6f %.6f %.6f" % (math.cos(t), height, math.sin(t))]
    lines += ["v 0 0 0", "v 0 %.6f 0" % height]
    bottom, top = 2 * sides + 1, 2 * sides + 2
    for k in range(sides):
        i0, i1 = 2 * k + 1, 2 * ((k + 1) % sides) + 1
        lines += ["f %d %d %d" % (i0, i1, i1 + 1), "f %d %d %d" % (i0, i1 + 1, i0 + 1),
                  "f %d %d %d" % (bottom, i1, i0), "f %d %d %d" % (top, i0 + 1, i1 + 1)]
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def axisymmetric_scene(a, f, work):
    """The axisymmetric case's scene at aspect ratio a and dx factor f: a
    cylinder of radius r_i = max(0.1, 0.1/a) m (its mesh written into
    `work`), a quarter of it in the domain's corner."""
    s = V.load_scene("granular_axisymmetric")
    dx = s["domain"]["dx"] * f
    floor = V.box_of(s, "floor")["max"][1]
    r = max(0.1, 0.1 / a)
    os.makedirs(work, exist_ok=True)
    mesh = os.path.join(work, "cylinder.obj")
    cylinder_obj(mesh, a)
    R = snap(r * (1 + 1.5 * V.axisymmetric_runout(a)) + 0.05, dx)
    Y = snap(floor + a * r + 0.06, dx)
    s["domain"].update(dx=dx, max=[R, Y, R])
    s["objects"][V.object_index(s, "column")]["shape"]["mesh"] = {
        "path": mesh, "scale": r, "translate": [0, floor, 0]}
    s["objects"][V.object_index(s, "floor")]["shape"]["box"] = {
        "min": [0, 0, 0], "max": [R, floor, R]}
    s["frames"] = {"count": int(round(collapse_duration(a) * 25)), "fps": 25}
    return s


def run_collapses(geometry, aspects, factors, work_root, threads, channel=None, grain=0.0):
    rows = []
    for a in aspects:
        for f in factors:
            work = os.path.join(work_root, "%s_a%g_dx%g" % (geometry, a, f))
            if geometry == "planar":
                scene, case = planar_scene(a, f, channel, grain), "granular_collapse"
            else:
                scene, case = axisymmetric_scene(a, f, work), "granular_axisymmetric"
            scene["solver"].update(SOLVER_EXTRA)
            r = V.run_one(case, scene, work, threads)
            # "H_inf/L0 1.337 vs 1.552 (err ..." -> the two heights.
            words = r["note"].split()
            height, ref_h = float(words[1]), float(words[3])
            rows.append(dict(geometry=geometry, a=a, dx=scene["domain"]["dx"],
                             channel=channel[0] if channel and geometry == "planar" else 0.0,
                             wall_friction=channel[1] if channel and geometry == "planar" else 0.0,
                             grain=grain if geometry == "planar" else 0.0,
                             runout=r["measured"], runout_ref=r["reference"], runout_err=r["error"],
                             signed=(r["measured"] - r["reference"]) / r["reference"],
                             height=height, height_ref=ref_h,
                             height_err=(height - ref_h) / ref_h, wall_s=r["wall_s"],
                             particles=r["particles"]))
            print("%-12s a=%-4g dx=%-6g run-out %.2f (fit %.2f, %+.0f%%)  H %.2f (fit %.2f)  %.0f s" % (
                geometry, a, scene["domain"]["dx"], r["measured"], r["reference"],
                100 * rows[-1]["signed"], height, ref_h, r["wall_s"]), flush=True)
    return rows


def dam_break_series(factors, work_root, threads):
    """The front Z(T) at each dx, read from the cache before it is removed."""
    base = V.load_scene("dam_break")
    curves, rows = [], []
    mt, mz, kt, kz = V.dam_break_reference()
    for f in factors:
        var = dict(name="dx x%g" % f, axis="dx", dx_factor=f, **V.BASE)
        scene = V.apply_variant(base, var)
        work = os.path.join(work_root, "dam_break_dx%g" % f)
        r = V.run_one("dam_break", scene, work, threads, inspect=V.dam_break_front)
        T, Z = r["inspected"]
        errs = {}
        for name, t, z in (("mm", mt, mz), ("ko", kt, kz)):
            sel = (t > 0) & (t <= T[-1])
            rel = (np.interp(t[sel], T, Z) - z[sel]) / z[sel]
            errs[name] = (math.sqrt(np.mean(rel ** 2)), float(rel.mean()))
        # The delay that best aligns the run with Martin & Moyce: the
        # experiment's front as if it had started late by dT.
        shifts = np.linspace(0, 0.6, 61)
        sel = (mt > 0) & (mt <= T[-1])
        cost = [np.mean(((np.interp(mt[sel] - s, T, Z) - mz[sel]) / mz[sel]) ** 2) for s in shifts]
        best = float(shifts[int(np.argmin(cost))])
        shifted = math.sqrt(min(cost))
        curves.append((scene["domain"]["dx"], T, Z))
        rows.append(dict(dx=scene["domain"]["dx"], mm_rms=errs["mm"][0], mm_mean=errs["mm"][1],
                         ko_rms=errs["ko"][0], ko_mean=errs["ko"][1], shift_T=best,
                         shifted_rms=shifted, wall_s=r["wall_s"], particles=r["particles"]))
        print("dam_break dx=%-7g vs Martin-Moyce RMS %.1f%% (mean %+.1f%%), vs Koshizuka-Oka RMS %.1f%% "
              "(mean %+.1f%%); best delay dT %.2f -> RMS %.1f%%  %.0f s" % (
                  rows[-1]["dx"], 100 * errs["mm"][0], 100 * errs["mm"][1], 100 * errs["ko"][0],
                  100 * errs["ko"][1], best, 100 * shifted, r["wall_s"]), flush=True)
    return rows, curves


def plot_collapses(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(8.4, 3.4), dpi=80)
    laws = {"planar": (V.lube_runout, V.lube_height, "Lube et al. 2005"),
            "axisymmetric": (V.axisymmetric_runout, V.axisymmetric_height,
                             "Lube et al. 2004 / Lajeunesse et al. 2004")}
    for ax, geometry in zip(axes, ("planar", "axisymmetric")):
        runout, height, source = laws[geometry]
        a = np.logspace(np.log10(0.3), np.log10(8), 200)
        ax.loglog(a, [runout(x) for x in a], "k-", lw=1, label="run-out, " + source)
        ax.loglog(a, [height(x) for x in a], "k--", lw=1, label="final height (fit)")
        rs = [r for r in rows if r["geometry"] == geometry]
        for k, dx in enumerate(sorted({r["dx"] for r in rs}, reverse=True)):
            d = sorted([r for r in rs if r["dx"] == dx], key=lambda r: r["a"])
            ax.loglog([r["a"] for r in d], [r["runout"] for r in d], "o", color="C%d" % k, ms=5,
                      label="run-out, dx %g m" % dx)
            ax.loglog([r["a"] for r in d], [r["height"] for r in d], "s", color="C%d" % k, ms=4,
                      mfc="none", label="height, dx %g m" % dx)
        ax.set_xlabel("aspect ratio a")
        ax.set_ylabel("(L - L0)/L0, H/L0" if geometry == "planar" else "(r - ri)/ri, H/ri")
        ax.set_title("%s collapse, Mohr-Coulomb 30 deg" % geometry, fontsize=9)
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_dam_break(curves, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    mt, mz, kt, kz = V.dam_break_reference()
    fig, ax = plt.subplots(figsize=(5.0, 3.6), dpi=80)
    for k, (dx, T, Z) in enumerate(sorted(curves, key=lambda c: -c[0])):
        ax.plot(T, Z, "-", color="C%d" % k, lw=1.2, label="Triad, dx %g m" % dx)
    ax.plot(mt, mz, "ko", ms=4, label="Martin & Moyce 1952 (a = 2.25 in)")
    ax.plot(kt, kz, "k^", ms=4, mfc="none", label="Koshizuka & Oka 1996")
    ax.set_xlim(0, 3.6)
    ax.set_ylim(1, 5)
    ax.set_xlabel("T = t sqrt(2g/a)")
    ax.set_ylabel("Z = front / a")
    ax.set_title("dam-break front at every dx", fontsize=9)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def write_csv(rows, path):
    if not rows:
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: V.fmt(v) for k, v in r.items()})


def write_markdown(collapse, dam, path, info, elapsed):
    lines = ["# Experiments across their parameter", "",
             "Command: `/usr/bin/python3 bench/validation/experiments.py` (2 threads). Machine: %s, "
             "%s cores. Wall time %.0f s." % (info.get("cpu", "?"), info["cores"], elapsed), ""]
    if collapse:
        lines += ["## Granular collapse against aspect ratio (Mohr-Coulomb, 30 deg)", "",
                  "Planar channel: the side walls' distance apart in m and their friction "
                  "(none: frictionless walls, an infinitely wide channel); grain: mu(I)'s "
                  "grain diameter in m (0: a constant friction).", "",
                  "| geometry | channel | grain | a | dx (m) | run-out | fit | error | H/L0 | fit "
                  "| wall s | particles |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in collapse:
            chan = "%g m, mu %g" % (r["channel"], r["wall_friction"]) if r["channel"] else "none"
            lines.append("| %s | %s | %g | %g | %g | %.2f | %.2f | %+.1f%% | %.2f | %.2f | %.0f | %d |" % (
                r["geometry"], chan, r["grain"], r["a"], r["dx"], r["runout"], r["runout_ref"],
                100 * r["signed"],
                r["height"], r["height_ref"], r["wall_s"], r["particles"]))
        lines += ["", "![collapse](collapse_aspect.png)", ""]
    if dam:
        lines += ["## Dam-break front at every dx", "",
                  "| dx (m) | vs Martin & Moyce: RMS (mean) | vs Koshizuka & Oka: RMS (mean) | "
                  "best delay dT | RMS after it | wall s |", "|---|---|---|---|---|---|"]
        for r in dam:
            lines.append("| %g | %.1f%% (%+.1f%%) | %.1f%% (%+.1f%%) | %.2f | %.1f%% | %.1f |" % (
                r["dx"], 100 * r["mm_rms"], 100 * r["mm_mean"], 100 * r["ko_rms"], 100 * r["ko_mean"],
                r["shift_T"], 100 * r["shifted_rms"], r["wall_s"]))
        lines += ["", "![dam break](dam_break_front.png)", ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--only", default="collapse,axisymmetric,dam_break")
    ap.add_argument("--results", default=os.path.join(HERE, "results"))
    ap.add_argument("--work", default=os.path.join(V.ROOT, "build", "validation", "experiments"))
    ap.add_argument("--triad", default=V.TRIAD)
    ap.add_argument("--aspects", default=",".join("%g" % a for a in PLANAR_A))
    ap.add_argument("--dx-factors", default=None)
    ap.add_argument("--grain-diameter", type=float, default=0.0)
    ap.add_argument("--channel-width", type=float, default=0.0)
    ap.add_argument("--wall-friction", type=float, default=0.4)
    ap.add_argument("--solver", default="{}")
    args = ap.parse_args()
    SOLVER_EXTRA.update(json.loads(args.solver))
    if args.channel_width < 0 or args.wall_friction < 0 or args.grain_diameter < 0:
        sys.exit("--channel-width, --wall-friction and --grain-diameter are not negative")
    V.TRIAD = os.path.abspath(args.triad)
    if not os.path.exists(V.TRIAD):
        sys.exit("%s not found: build it first (scripts/build.sh release triad)" % V.TRIAD)
    only = set(args.only.split(","))
    os.makedirs(args.results, exist_ok=True)
    t0 = V.time.time()
    factors = [1] if args.quick else COLLAPSE_DX
    if args.dx_factors:
        factors = [float(f) for f in args.dx_factors.split(",")]
    aspects = [float(a) for a in args.aspects.split(",")]
    channel = (args.channel_width, args.wall_friction) if args.channel_width > 0 else None
    collapse, dam, curves = [], [], []
    if "collapse" in only:
        collapse += run_collapses("planar", aspects, factors, args.work, args.threads, channel,
                                  args.grain_diameter)
    if "axisymmetric" in only:
        collapse += run_collapses("axisymmetric", AXISYMMETRIC_A, factors, args.work, args.threads)
    if "dam_break" in only:
        dam, curves = dam_break_series([2, 1] if args.quick else DAM_BREAK_DX, args.work, args.threads)
    if collapse:
        write_csv(collapse, os.path.join(args.results, "collapse_aspect.csv"))
        plot_collapses(collapse, os.path.join(args.results, "collapse_aspect.png"))
    if dam:
        write_csv(dam, os.path.join(args.results, "dam_break_front.csv"))
        plot_dam_break(curves, os.path.join(args.results, "dam_break_front.png"))
    write_markdown(collapse, dam, os.path.join(args.results, "experiments.md"), V.machine_info(),
                   V.time.time() - t0)
    print("results in %s (%.0f s)" % (args.results, V.time.time() - t0))
    return 0


if __name__ == "__main__":
    sys.exit(main())
