#!/usr/bin/python3
"""Accuracy against cost (issue 7): runs the validation scenes with the
`triad` CLI over sweeps of dx, particles_per_cell, cfl and transfer, measures
each run against its reference (analytic or published experiment), and
writes CSV rows, PNG plots and a markdown summary.

Usage (from the repository root; bench/validation/run.sh wraps it):
  /usr/bin/python3 bench/validation/validate.py [--quick] [--threads N]
      [--cases a,b] [--check-only] [--no-check] [--results DIR]

--quick       a smaller sweep (coarse dx only, no ppc 27), for a smoke test
--check-only  only the presets stage: every case at --quality draft, preview and
              final; the analytic cases must pass their tolerance at final
--no-check    the sweep only
--suite       the regression guard ctest runs (label `validation`): each case
              once, at the preset where it is documented to pass (SUITE),
              against its tolerance; writes no results, exits 1 on a miss
--triad PATH  the triad executable (default build/app/triad)

Needs Debian's python3 with numpy and matplotlib (apt: python3-numpy,
python3-matplotlib) and a built build/app/triad.
"""
import argparse
import copy
import csv
import functools
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENES = os.path.join(HERE, "scenes")
DATA = os.path.join(HERE, "data")
TRIAD = os.path.join(ROOT, "build", "app", "triad")
G = 9.81


# ----------------------------------------------------------------------------
# Reading the cache

def read_ply(path):
    """Binary little-endian PLY of particles -> dict of numpy arrays."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        count = 0
        fields = []
        types = {"float": "<f4", "int": "<i4", "double": "<f8", "uchar": "u1", "uint": "<u4"}
        for line in header:
            parts = line.split()
            if parts[:2] == ["element", "vertex"]:
                count = int(parts[2])
            elif parts and parts[0] == "property" and parts[1] != "list":
                fields.append((parts[2], types[parts[1]]))
        data = np.frombuffer(f.read(count * np.dtype(fields).itemsize), dtype=np.dtype(fields),
                             count=count)
    return {name: data[name] for name, _ in fields}


def ply_path(out, frame):
    return os.path.join(out, "particles", "particles.%04d.ply" % frame)


def read_rigid_states(out, name):
    rows = []
    with open(os.path.join(out, "bodies", "rigid_states.csv")) as f:
        for r in csv.DictReader(f):
            if r["name"] == name:
                rows.append({k: (float(v) if k != "name" else v) for k, v in r.items()})
    return rows


def box_of(scene, name):
    for o in scene["objects"]:
        if o["name"] == name:
            return o["shape"]["box"]
    raise KeyError(name)


def object_index(scene, name):
    return [o["name"] for o in scene["objects"]].index(name)


# ----------------------------------------------------------------------------
# Measurements: each returns (quantity, measured, reference, relative error, note)

def measure_free_fall(scene, out):
    n = scene["frames"]["count"]
    t = n / scene["frames"]["fps"]
    y0 = read_ply(ply_path(out, 0))["y"].astype(np.float64).mean()
    y1 = read_ply(ply_path(out, n))["y"].astype(np.float64).mean()
    ref = 0.5 * G * t * t
    drop = y0 - y1
    return "drop at t=%.2f s (m)" % t, drop, ref, abs(drop - ref) / ref, ""


def measure_incline(scene, out):
    fps = scene["frames"]["fps"]
    k = object_index(scene, "block")
    gx, gy = scene["gravity"][0], scene["gravity"][1]
    g = math.hypot(gx, gy)
    sin, cos = gx / g, -gy / g
    mu = [o for o in scene["objects"] if o["name"] == "slab"][0]["friction"]
    v = []
    for f in (1, 3):
        p = read_ply(ply_path(out, f))
        v.append(p["vx"][p["object"] == k].astype(np.float64).mean())
    a = (v[1] - v[0]) / (2.0 / fps)
    ref = g * (sin - mu * cos)
    p = read_ply(ply_path(out, 3))
    ymin = p["y"][p["object"] == k].min()
    note = "block bottom %.4f m (slab top %.2f)" % (ymin, box_of(scene, "slab")["max"][1])
    return "acceleration along slope (m/s^2)", a, ref, abs(a - ref) / ref, note


def measure_archimedes(scene, out):
    fps = scene["frames"]["fps"]
    slab = box_of(scene, "slab")
    rho_s = [o for o in scene["objects"] if o["name"] == "slab"][0]["density"]
    mat = scene["materials"]["water"]
    rho_w = mat["density"]
    h = slab["max"][1] - slab["min"][1]
    area = (slab["max"][0] - slab["min"][0]) * (slab["max"][2] - slab["min"][2])
    tank = ((scene["domain"]["max"][0] - scene["domain"]["min"][0]) *
            (scene["domain"]["max"][2] - scene["domain"]["min"][2]))
    rows = [r for r in read_rigid_states(out, "slab") if r["time"] >= 1.0 - 1e-9]
    # The slab's collision particles span h about its centre of mass.
    bottom = np.mean([r["py"] for r in rows]) - h / 2
    # Water level: the water's volume (particle volumes times J, averaged over
    # the same frames) plus the displaced volume (the slab's mass over the
    # water's density), spread over the tank.
    k = object_index(scene, "water")
    v0 = scene["domain"]["dx"] ** 3 / scene["solver"]["particles_per_cell"]
    vol = np.mean([read_ply(ply_path(out, int(round(r["frame"]))))["J"][
        read_ply(ply_path(out, int(round(r["frame"]))))["object"] == k].astype(np.float64).sum() * v0
        for r in rows])
    level = vol / tank + rho_s * area * h / (rho_w * tank)
    ref = rho_s / rho_w * h
    draft = level - bottom
    # The slab's drift over the last frames, from its positions: its
    # end-of-frame velocity samples a fast heave on the water's stiffness.
    k = min(3, len(rows) - 1)
    drift = (rows[-1]["py"] - rows[-1 - k]["py"]) * fps / k if k > 0 else float("nan")
    return ("draft (m), mean over t>=1 s", draft, ref, abs(draft - ref) / ref,
            "slab moving %+.4f m/s over the last %d frames" % (drift, k))


def measure_bar(scene, out):
    n = scene["frames"]["count"]
    fps = scene["frames"]["fps"]
    kl, kr = object_index(scene, "left"), object_index(scene, "right")
    t, s = [], []
    for f in range(n + 1):
        p = read_ply(ply_path(out, f))
        x = p["x"].astype(np.float64)
        s.append(x[p["object"] == kr].mean() - x[p["object"] == kl].mean())
        t.append(f / fps)
    t, s = np.array(t), np.array(s) - s[0]
    # Zero crossings of the halves' separation: every half period.
    amp = np.abs(s).max()
    cross = []
    armed = False
    for i in range(1, len(s)):
        if abs(s[i]) > 0.3 * amp:
            armed = True
        if armed and s[i - 1] != 0 and np.sign(s[i]) != np.sign(s[i - 1]):
            cross.append(t[i - 1] + (t[i] - t[i - 1]) * s[i - 1] / (s[i - 1] - s[i]))
            armed = False
    mat = scene["materials"]["rod"]
    c = math.sqrt(mat["youngs_modulus"] / mat["density"])
    L = box_of(scene, "right")["max"][0] - box_of(scene, "left")["min"][0]
    ref = 2 * L / c
    if len(cross) < 2:
        return "period (s)", float("nan"), ref, float("nan"), "fewer than 2 zero crossings"
    k = np.arange(1, len(cross) + 1)
    half = np.polyfit(k, np.array(cross), 1)[0]
    T = 2 * half
    # Amplitude kept after the run: numerical damping.
    return ("axial period (s)", T, ref, abs(T - ref) / ref,
            "%d crossings; last-period amplitude / first %.2f" %
            (len(cross), np.abs(s[len(s) // 2:]).max() / amp))


def scaling_law(name, quantity, a):
    """The fitted law c * a^p of data file `name` for `quantity` at aspect ratio
    a; nan between regimes, where the paper claims neither law."""
    lo, hi = law_bracket(name, quantity, a)
    return lo if lo == hi else float("nan")


def law_bracket(name, quantity, a):
    """The values at a of the laws of data file `name` for `quantity`: the
    one law's value twice inside a regime; between regimes the two
    neighbouring laws' values, smaller first."""
    rows = [r for r in load_data(name) if r["quantity"] == quantity]
    law = lambda r: float(r["coefficient"]) * a ** float(r["exponent"])
    for r in rows:
        if float(r["a_min"]) <= a < float(r["a_max"]):
            return law(r), law(r)
    below = max((r for r in rows if float(r["a_max"]) <= a), key=lambda r: float(r["a_max"]))
    above = min((r for r in rows if float(r["a_min"]) > a), key=lambda r: float(r["a_min"]))
    return tuple(sorted((law(below), law(above))))


def lube_runout(a):
    # Lube et al. 2005: (d_inf - d_i)/d_i = 1.2 a (a < 1.8), 1.9 a^(2/3) (a > 2.8)
    return scaling_law(PLANAR_FITS, "runout", a)


def lube_height(a):
    # Lube et al. 2005: h_inf/d_i = a (a < 1.15), a^(2/5) (a > 1.15)
    return scaling_law(PLANAR_FITS, "final_height", a)


def runout_error(measured, a, name):
    """Relative error of a run-out against the fitted laws of data file
    `name`; between regimes (the planar fits' 1.8 < a < 2.8) against the
    nearer of the two neighbouring laws' values, zero between them."""
    lo, hi = law_bracket(name, "runout", a)
    if lo <= measured <= hi:
        return 0.5 * (lo + hi), 0.0
    ref = lo if measured < lo else hi
    return ref, abs(measured - ref) / ref


PLANAR_FITS = "lube_2005_granular_collapse.csv"
AXISYMMETRIC_FITS = "lube_2004_axisymmetric_collapse.csv"


def axisymmetric_runout(a):
    # Lube et al. 2004: (r_inf - r_i)/r_i = 1.24 a (a < 1.7), 1.6 a^(1/2) (a > 1.7)
    return scaling_law(AXISYMMETRIC_FITS, "runout", a)


def axisymmetric_height(a):
    # Lajeunesse et al. 2004: h_inf/r_i = a (a < 0.74), 0.74 (a > 0.74)
    return scaling_law(AXISYMMETRIC_FITS, "final_height", a)


def mesh_extent(scene, name):
    """Radius about the y axis and height of an object's mesh (an OBJ), in
    world units: its vertices scaled and translated as the scene says."""
    for o in scene["objects"]:
        if o["name"] == name:
            m = o["shape"]["mesh"]
            break
    else:
        raise KeyError(name)
    scale, t = m.get("scale", 1.0), m.get("translate", [0, 0, 0])
    v = []
    with open(m["path"]) as f:
        for line in f:
            if line.startswith("v "):
                v.append([float(c) for c in line.split()[1:4]])
    v = np.array(v) * scale + np.array(t)
    return float(np.hypot(v[:, 0], v[:, 2]).max()), float(v[:, 1].min()), float(v[:, 1].max())


def measure_axisymmetric(scene, out):
    n = scene["frames"]["count"]
    r_i, y0, y1 = mesh_extent(scene, "column")
    a = (y1 - y0) / r_i
    p0, pn, pm = read_ply(ply_path(out, 0)), read_ply(ply_path(out, n)), read_ply(ply_path(out, n - 5))
    radius = lambda p: np.hypot(p["x"].astype(np.float64), p["z"].astype(np.float64))
    # As for the planar case: from the initial outermost particle, not the
    # mesh, since the particle lattice lies inside the surface.
    runout = (radius(pn).max() - radius(p0).max()) / r_i
    height = (pn["y"].max() + (y1 - p0["y"].max()) - y0) / r_i
    moved = (radius(pn).max() - radius(pm).max()) / r_i
    ref, err = runout_error(runout, a, AXISYMMETRIC_FITS)
    ref_h = axisymmetric_height(a)
    return ("runout (r_inf-r_i)/r_i at a=%.1f" % a, runout, ref, err,
            "H_inf/r_i %.3f vs %.3f (err %.1f%%); edge moved %.3f r_i in the last 5 frames" %
            (height, ref_h, 100 * abs(height - ref_h) / ref_h, moved))


def measure_granular(scene, out):
    n = scene["frames"]["count"]
    col = box_of(scene, "column")
    L0 = col["max"][0] - col["min"][0]
    H0 = col["max"][1] - col["min"][1]
    a = H0 / L0
    p0, p1, pn = read_ply(ply_path(out, 0)), read_ply(ply_path(out, n - 1)), read_ply(ply_path(out, n))
    # Offsets of the particle lattice inside the cells: compare with the
    # initial extreme particles, not the box faces.
    runout = (pn["x"].max() - p0["x"].max()) / L0
    # Heights from the floor the column stands on (a rigid box under it).
    height = (pn["y"].max() + (col["max"][1] - p0["y"].max()) - col["min"][1]) / L0
    moved = (pn["x"].max() - p1["x"].max()) / L0
    ref_r, err = runout_error(runout, a, PLANAR_FITS)
    ref_h = lube_height(a)
    err_h = abs(height - ref_h) / ref_h
    return ("runout (L_inf-L0)/L0 at a=%.1f" % a, runout, ref_r, err,
            "H_inf/L0 %.3f vs %.3f (err %.1f%%); front moved %.3f L0 in the last frame" %
            (height, ref_h, 100 * err_h, moved))


@functools.lru_cache(maxsize=None)
def load_data(name):
    """The rows of a data file as dicts (cached: the fitted laws read theirs
    for every point they are evaluated at). Callers must not change them."""
    rows = []
    with open(os.path.join(DATA, name)) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            rows.append(line.strip().split(","))
    header, body = rows[0], rows[1:]
    return [dict(zip(header, r)) for r in body]


def dam_break_reference():
    mm = [r for r in load_data("martin_moyce_1952_dam_break.csv") if r["a_inch"] == "2.25"]
    ko = load_data("koshizuka_oka_1996_dam_break.csv")
    return (np.array([float(r["T"]) for r in mm]), np.array([float(r["Z"]) for r in mm]),
            np.array([float(r["T"]) for r in ko]), np.array([float(r["Z"]) for r in ko]))


def dam_break_front(scene, out):
    """The front Z = z/a (farthest particle) against T = t sqrt(2g/a), every frame."""
    n = scene["frames"]["count"]
    fps = scene["frames"]["fps"]
    col = box_of(scene, "column")
    a = col["max"][0] - col["min"][0]
    x0 = read_ply(ply_path(out, 0))["x"].max()
    T, Z = [], []
    for f in range(n + 1):
        p = read_ply(ply_path(out, f))
        T.append(f / fps * math.sqrt(2 * G / a))
        Z.append((p["x"].max() - x0 + a) / a)
    return np.array(T), np.array(Z)


def measure_dam_break(scene, out):
    T, Z = dam_break_front(scene, out)
    mt, mz, kt, kz = dam_break_reference()
    sel = (mt > 0) & (mt <= T[-1])
    rel = (np.interp(mt[sel], T, Z) - mz[sel]) / mz[sel]
    ksel = (kt > 0) & (kt <= T[-1])
    krel = (np.interp(kt[ksel], T, Z) - kz[ksel]) / kz[ksel]
    rms = math.sqrt(np.mean(rel ** 2))
    krms = math.sqrt(np.mean(krel ** 2))
    return ("front Z=z/a vs T, RMS rel. error (%d points)" % sel.sum(), float(np.interp(3.0, T, Z)),
            float(np.interp(3.0, mt, mz)), rms,
            "measured/reference are Z at T=3; mean signed error %+.1f%%; vs Koshizuka-Oka RMS %.1f%%" %
            (100 * rel.mean(), 100 * krms))


# ----------------------------------------------------------------------------
# Cases

CASES = {
    # name: scene, measure, analytic?, tolerance at --quality final, dx factors of the sweep
    "free_fall": dict(scene="free_fall.json", measure=measure_free_fall, analytic=True, tol=0.01,
                      dx=[2, 1, 0.5, 0.25], quick_dx=[2, 1]),
    "incline": dict(scene="incline.json", measure=measure_incline, analytic=True, tol=0.05,
                    dx=[2, 1, 0.5, 0.25], quick_dx=[2, 1]),
    # Full 3D: a rigid slab spanning a quasi-2D slab of cells lets water leak
    # past its z faces along the domain walls (bench/RESULTS.md).
    "archimedes": dict(scene="archimedes.json", measure=measure_archimedes, analytic=True,
                       tol=0.05, dx=[2, 1, 0.5], quick_dx=[2, 1], quasi2d=False),
    "bar": dict(scene="bar.json", measure=measure_bar, analytic=True, tol=0.02,
                dx=[2, 1, 0.5, 0.25], quick_dx=[2, 1]),
    "granular_collapse": dict(scene="granular_collapse.json", measure=measure_granular,
                              analytic=False, tol=0.20, dx=[2, 1, 0.5], quick_dx=[2, 1]),
    # A quarter of the cylinder, at the corner of frictionless walls (its
    # planes of symmetry), on a rough fixed floor.
    "granular_axisymmetric": dict(scene="granular_axisymmetric.json", measure=measure_axisymmetric,
                                  analytic=False, tol=0.20, dx=[2, 1, 0.5], quick_dx=[2, 1],
                                  quasi2d=False),
    "dam_break": dict(scene="dam_break.json", measure=measure_dam_break, analytic=False,
                      tol=0.10, dx=[2, 1, 0.5, 0.25], quick_dx=[2, 1]),
}

BASE = dict(ppc=8, cfl=0.4, transfer="apic")

# The regression guard (--suite): each case at `preview` (the scene's own
# dx), 9-12 s apiece on 2 threads, against its tolerance, so that a change
# that breaks a documented figure fails the suite.
SUITE = {"free_fall": "preview", "incline": "preview", "bar": "preview",
         "dam_break": "preview", "granular_collapse": "preview", "archimedes": "preview",
         "granular_axisymmetric": "preview"}
# Known misses, pinned: the measured error and how far it may move before the
# guard fails, so that a fix or a worse miss is seen and this is updated.
# Archimedes at preview: the dropped slab comes to rest 0.7 cells above its
# draft and creeps down at under a millimetre a second (0.5 cells high at
# 4.8 s). Placed at rest in the water it stays wherever it is put within a
# band about 0.8 cells wide round its draft, and dropped it lands at the
# band's top with the water under it nearly unloaded (bench/RESULTS.md,
# "The validation's slab rests anywhere in a band", and "The stall"). With
# rigid_collision "jacobi" it sank on past Archimedes' draft (0.064 m at
# 6 s, 18% in the window).
# The axisymmetric collapse at preview (10 cells across the column's
# radius) runs out 35% short once the sand rests on the fixed floor rather
# than a cell above it (solver.contact_gap_fixed, the default): the 19%
# short it read before leaned on that hover. At dx 0.005 it reads -3%; the
# run-out grows with refinement with and without the gap (bench/RESULTS.md,
# "The contact gap for fixed solids").
KNOWN_MISS = {"archimedes": (0.3073, 0.02), "granular_axisymmetric": (0.3522, 0.02)}


def variants(case, quick):
    c = CASES[case]
    out = []
    for f in (c["quick_dx"] if quick else c["dx"]):
        out.append(dict(name="dx x%g" % f, axis="dx", dx_factor=f, **BASE))
    sweep = [("ppc", [4] if quick else [4, 27]), ("cfl", [0.2, 0.8]),
             ("transfer", ["pic", "flip"])]
    for axis, values in sweep:
        for v in values:
            var = dict(name="%s %s" % (axis, v), axis=axis, dx_factor=1, **BASE)
            var[axis] = v
            out.append(var)
    return out


def load_scene(case):
    with open(os.path.join(SCENES, CASES[case]["scene"])) as f:
        scene = json.load(f)
    # Runs write their scene elsewhere: mesh paths made absolute.
    for o in scene["objects"]:
        m = o["shape"].get("mesh")
        if m and not os.path.isabs(m["path"]):
            m["path"] = os.path.join(SCENES, m["path"])
    return scene


def apply_variant(scene, var, quasi2d=True):
    """The scene with dx scaled, and, when quasi-2D (a slab of cells in z),
    its z extents scaled with dx so that it stays 4 cells thick."""
    s = copy.deepcopy(scene)
    f = var["dx_factor"]
    s["domain"]["dx"] = scene["domain"]["dx"] * f
    if quasi2d:
        s["domain"]["max"][2] = scene["domain"]["max"][2] * f
        for o in s["objects"]:
            b = o["shape"]["box"]
            b["min"][2] *= f
            b["max"][2] *= f
    s["solver"]["particles_per_cell"] = var["ppc"]
    s["solver"]["cfl"] = var["cfl"]
    s["solver"]["transfer"] = var["transfer"]
    return s


def run_triad(scene_path, out, threads, extra=()):
    if os.path.exists(out):
        shutil.rmtree(out)
    env = dict(os.environ, OMP_WAIT_POLICY="passive")
    cmd = [TRIAD, "run", scene_path, "--out", out, "--threads", str(threads), "--quiet"] + list(extra)
    t0 = time.time()
    r = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=1800)
    wall = time.time() - t0
    if r.returncode != 0:
        raise RuntimeError("%s exited %d: %s" % (" ".join(cmd), r.returncode, r.stderr[-2000:]))
    with open(os.path.join(out, "run.json")) as f:
        rec = json.load(f)
    return wall, rec


def run_one(case, scene, work, threads, extra=(), keep=False, inspect=None):
    """Runs a case's scene and measures it; `inspect(scene, out)`, if given,
    reads more from the cache before it goes (its result: "inspected")."""
    os.makedirs(work, exist_ok=True)
    path = os.path.join(work, "scene.json")
    with open(path, "w") as f:
        json.dump(scene, f, indent=1)
    out = os.path.join(work, "cache")
    wall, rec = run_triad(path, out, threads, extra)
    # Under --quality the run's dx and particles per cell are the preset's
    # (run.json records them): measure against those, not the file's.
    q = rec.get("quality")
    if isinstance(q, dict) and "dx" in q:
        scene = copy.deepcopy(scene)
        scene["domain"]["dx"] = q["dx"]
        scene["solver"]["particles_per_cell"] = q.get("particles_per_cell",
                                                      scene["solver"]["particles_per_cell"])
    quantity, measured, ref, err, note = CASES[case]["measure"](scene, out)
    inspected = inspect(scene, out) if inspect else None
    if not keep:
        shutil.rmtree(out)
    return dict(wall_s=wall, solve_s=rec["wall_seconds"]["phases"].get("solve", 0.0),
                particles=rec["particles"]["total"], steps=rec["steps"], quantity=quantity,
                measured=measured, reference=ref, error=err, note=note, run=rec,
                inspected=inspected)


FIELDS = ["case", "variant", "axis", "dx", "ppc", "cfl", "transfer", "quantity", "measured",
          "reference", "error", "wall_s", "solve_s", "particles", "steps", "note"]


def fmt(v):
    if isinstance(v, float):
        return "%.6g" % v
    return v


def machine_info():
    info = {"host": platform.node(), "kernel": platform.release(), "cores": os.cpu_count()}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    info["cpu"] = line.split(":", 1)[1].strip()
                    break
        with open("/proc/meminfo") as f:
            info["memory_gib"] = round(int(f.readline().split()[1]) / 2 ** 20, 1)
    except OSError:
        pass
    return info


def uptime():
    try:
        return subprocess.run(["uptime"], stdout=subprocess.PIPE, text=True).stdout.strip()
    except OSError:
        return "?"


# ----------------------------------------------------------------------------
# Analysis

def convergence_order(rows):
    """Least-squares slope of log(error) against log(dx) over the dx series,
    and the local orders between neighbouring dx."""
    pts = sorted([(r["dx"], r["error"]) for r in rows if r["axis"] == "dx" and r["error"] > 0
                  and math.isfinite(r["error"])])
    if len(pts) < 2:
        return float("nan"), [], "too few points"
    x = np.log([p[0] for p in pts])
    y = np.log([p[1] for p in pts])
    p = np.polyfit(x, y, 1)[0]
    local = [(y[i + 1] - y[i]) / (x[i + 1] - x[i]) for i in range(len(pts) - 1)]
    errs = [e for _, e in pts]
    monotone = all(errs[i] <= errs[i + 1] for i in range(len(errs) - 1))
    signs = {math.copysign(1, r["measured"] - r["reference"]) for r in rows
             if r["axis"] == "dx" and math.isfinite(r["measured"])}
    if len(signs) > 1:
        verdict = ("not asymptotic: the error changes sign along the dx series, so the "
                   "fitted order of |error| means little")
    elif not monotone:
        verdict = "not asymptotic: the error does not fall monotonically with dx"
    elif len(local) >= 2 and max(local) - min(local) > 0.6:
        verdict = "not clearly asymptotic: local orders %s" % ", ".join("%.2f" % l for l in local)
    else:
        verdict = "consistent local orders"
    return p, local, verdict


def plot_case(case, rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(8.4, 3.3), dpi=80)
    colours = {"dx": "C0", "ppc": "C1", "cfl": "C2", "transfer": "C3"}
    for axis, col in colours.items():
        rs = sorted([r for r in rows if r["axis"] == axis], key=lambda r: r["wall_s"])
        if axis != "dx":
            base = [r for r in rows if r["axis"] == "dx" and r["dx_factor"] == 1]
            rs = sorted(rs + base, key=lambda r: r["wall_s"])
        ax1.plot([r["wall_s"] for r in rs], [max(r["error"], 1e-6) for r in rs], "o-",
                 color=col, label=axis, ms=4, lw=1)
        for r in rs:
            if r["axis"] == axis:
                ax1.annotate(r["variant"].split(" ", 1)[1], (r["wall_s"], max(r["error"], 1e-6)),
                             fontsize=6, xytext=(3, 2), textcoords="offset points")
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_xlabel("wall seconds (2 threads)")
    ax1.set_ylabel("relative error")
    ax1.set_title("%s: error against cost" % case, fontsize=9)
    ax1.legend(fontsize=7)
    ax1.grid(True, which="both", lw=0.3)
    d = sorted([r for r in rows if r["axis"] == "dx"], key=lambda r: r["dx"])
    ax2.loglog([r["dx"] for r in d], [max(r["error"], 1e-6) for r in d], "o-", color="C0", ms=4)
    p, _, _ = convergence_order(rows)
    if math.isfinite(p) and len(d) >= 2:
        x = np.array([d[0]["dx"], d[-1]["dx"]])
        ax2.loglog(x, d[-1]["error"] * (x / d[-1]["dx"]) ** p, "--", color="0.5",
                   label="fit: order %.2f" % p)
        ax2.legend(fontsize=7)
    ax2.set_xlabel("dx (m)")
    ax2.set_ylabel("relative error")
    ax2.set_title("convergence in dx", fontsize=9)
    ax2.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def write_summary(rows, results, info, command, load_before, load_after, elapsed, checks):
    lines = ["# Validation: accuracy against cost", "",
             "Command: `%s`" % command, "",
             "Machine: %s, %s cores, %s GiB, kernel %s." % (info.get("cpu", "?"), info["cores"],
                                                           info.get("memory_gib", "?"),
                                                           info["kernel"]),
             "", "Load before: `%s`" % load_before, "", "Load after: `%s`" % load_after, "",
             "Total wall time of the sweep: %.0f s." % elapsed, ""]
    for case in CASES:
        rs = [r for r in rows if r["case"] == case]
        if not rs:
            continue
        lines += ["## %s" % case, "", "Quantity: %s." % rs[0]["quantity"], "",
                  "| variant | dx | ppc | cfl | transfer | measured | reference | error | wall s | particles | steps |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rs:
            lines.append("| %s | %g | %d | %g | %s | %.4g | %.4g | %.2f%% | %.1f | %d | %d |" % (
                r["variant"], r["dx"], r["ppc"], r["cfl"], r["transfer"], r["measured"],
                r["reference"], 100 * r["error"], r["wall_s"], r["particles"], r["steps"]))
        notes = ["%s: %s" % (r["variant"], r["note"]) for r in rs if r["note"]]
        p, local, verdict = convergence_order(rs)
        lines += ["", "Observed order in dx: %.2f (%s)." % (p, verdict), ""]
        if notes:
            lines += ["Notes: " + "; ".join(notes) + ".", ""]
        lines += ["![%s](%s.png)" % (case, case), ""]
    if checks:
        lines += ["## Each case at each `--quality` preset", "",
                  "The scenes as written (quasi-2D slabs keep their 4 base cells in z, so 8 at "
                  "`final`). Pass/miss: analytic cases against their tolerance; the experiments "
                  "against theirs, for information.", "",
                  "| case | quality | dx | ppc | cfl | transfer | measured | reference | error | tolerance | result | wall s | particles |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for c in checks:
            lines.append("| %s | %s | %g | %d | %g | %s | %.4g | %.4g | %.2f%% | %.0f%% | %s | %.1f | %d |" % (
                c["case"], c["quality"], c["dx"], c["ppc"], c["cfl"], c["transfer"], c["measured"],
                c["reference"], 100 * c["error"], 100 * c["tol"],
                "pass" if c["pass"] else "**miss**", c["wall_s"], c["particles"]))
        lines.append("")
    with open(os.path.join(results, "summary.md"), "w") as f:
        f.write("\n".join(lines))


PRESETS = ["draft", "preview", "final"]


def run_presets(cases, work_root, threads, results):
    """Every case, as written, at each --quality preset; the analytic cases at
    `final` against their tolerance."""
    rows = []
    for case in cases:
        for q in PRESETS:
            scene = load_scene(case)
            try:
                r = run_one(case, scene, os.path.join(work_root, case, q), threads, ["--quality", q])
            except Exception as e:
                r = dict(wall_s=float("nan"), particles=0, steps=0, measured=float("nan"),
                         reference=float("nan"), error=float("nan"), note="FAILED: %s" % str(e)[-300:],
                         run={})
            qrec = r["run"].get("quality", {})
            tol = CASES[case]["tol"]
            ok = math.isfinite(r["error"]) and r["error"] <= tol
            rows.append(dict(case=case, quality=q, dx=qrec.get("dx", float("nan")),
                             ppc=qrec.get("particles_per_cell", 0), cfl=qrec.get("cfl", float("nan")),
                             transfer=qrec.get("transfer", ""), measured=r["measured"],
                             reference=r["reference"], error=r["error"], tol=tol,
                             analytic=CASES[case]["analytic"], wall_s=r["wall_s"],
                             particles=r["particles"], steps=r["steps"], note=r["note"],
                             **{"pass": ok}))
            print("%-18s --quality %-8s error %8.3f%% (tolerance %.0f%%) %s %7.1f s %7d particles" % (
                case, q, 100 * r["error"], 100 * tol, "pass" if ok else "MISS", r["wall_s"],
                r["particles"]), flush=True)
    with open(os.path.join(results, "presets.csv"), "w", newline="") as f:
        fields = ["case", "quality", "dx", "ppc", "cfl", "transfer", "measured", "reference",
                  "error", "tol", "analytic", "pass", "wall_s", "particles", "steps", "note"]
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for c in rows:
            w.writerow({k: fmt(c[k]) for k in fields})
    return rows


def load_rows(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            for k in ("dx", "cfl", "measured", "reference", "error", "wall_s", "solve_s"):
                r[k] = float(r[k]) if r[k] else float("nan")
            for k in ("ppc", "particles", "steps"):
                r[k] = int(float(r[k])) if r[k] else 0
            r["dx_factor"] = float(r["variant"].split("x")[-1]) if r["axis"] == "dx" else 1.0
            rows.append(r)
    return rows


def run_suite(cases, work_root, threads):
    """Each case once at its SUITE preset: pass or miss against its tolerance."""
    misses = 0
    for case in cases:
        q = SUITE[case]
        work = os.path.join(work_root, case, "suite_" + q)
        r = run_one(case, load_scene(case), work, threads, ["--quality", q])
        tol = CASES[case]["tol"]
        if case in KNOWN_MISS:
            pinned, band = KNOWN_MISS[case]
            ok = math.isfinite(r["error"]) and abs(r["error"] - pinned) <= band
            verdict = ("known miss, as pinned (%.2f%% +- %.0f%%)" if ok else
                       "CHANGED from the pinned known miss (%.2f%% +- %.0f%%): update KNOWN_MISS") % (
                           100 * pinned, 100 * band)
        else:
            ok = math.isfinite(r["error"]) and r["error"] <= tol
            verdict = "pass" if ok else "MISS"
        misses += 0 if ok else 1
        kind = "analytic" if CASES[case]["analytic"] else "experiment"
        print("%s --quality %s: %s %.6g, reference (%s) %.6g, error %.2f%% (tolerance %.0f%%): %s"
              "%s" % (case, q, r["quantity"], r["measured"], kind, r["reference"],
                      100 * r["error"], 100 * tol, verdict,
                      "; " + r["note"] if r["note"] else ""), flush=True)
        shutil.rmtree(work, ignore_errors=True)
    return 1 if misses else 0


def main():
    global TRIAD
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--check-only", action="store_true")
    ap.add_argument("--no-check", action="store_true")
    ap.add_argument("--results", default=os.path.join(HERE, "results"))
    ap.add_argument("--work", default=os.path.join(ROOT, "build", "validation"))
    ap.add_argument("--suite", action="store_true")
    ap.add_argument("--triad", default=TRIAD)
    args = ap.parse_args()
    TRIAD = os.path.abspath(args.triad)
    cases = [c for c in args.cases.split(",") if c]
    for c in cases:
        if c not in CASES:
            sys.exit("unknown case %r; known: %s" % (c, ", ".join(CASES)))
    if not os.path.exists(TRIAD):
        sys.exit("%s not found: build it first (scripts/build.sh release triad)" % TRIAD)
    if args.suite:
        return run_suite(cases, args.work, args.threads)
    os.makedirs(args.results, exist_ok=True)
    command = "bench/validation/run.sh" + (" --quick" if args.quick else "") + \
        ("" if args.threads == 2 else " --threads %d" % args.threads)
    info = machine_info()
    load_before = uptime()
    t0 = time.time()
    rows = []
    if not args.check_only:
        csv_path = os.path.join(args.results, "runs.csv")
        with open(csv_path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=FIELDS)
            w.writeheader()
            for case in cases:
                base = load_scene(case)
                for var in variants(case, args.quick):
                    scene = apply_variant(base, var, CASES[case].get("quasi2d", True))
                    tag = var["name"].replace(" ", "_")
                    try:
                        r = run_one(case, scene, os.path.join(args.work, case, tag), args.threads)
                    except Exception as e:  # a failed run is a row too
                        r = dict(wall_s=float("nan"), solve_s=float("nan"), particles=0, steps=0,
                                 quantity="", measured=float("nan"), reference=float("nan"),
                                 error=float("nan"), note="FAILED: %s" % str(e)[-300:])
                    row = dict(case=case, variant=var["name"], axis=var["axis"],
                               dx=scene["domain"]["dx"], dx_factor=var["dx_factor"],
                               ppc=var["ppc"], cfl=var["cfl"], transfer=var["transfer"])
                    row.update({k: r[k] for k in FIELDS if k in r})
                    rows.append(row)
                    w.writerow({k: fmt(row[k]) for k in FIELDS})
                    f.flush()
                    print("%-18s %-14s error %8.3f%%  %7.1f s  %7d particles  %s" % (
                        case, var["name"], 100 * row["error"], row["wall_s"], row["particles"],
                        row["note"]), flush=True)
                plot_case(case, [r for r in rows if r["case"] == case],
                          os.path.join(args.results, case + ".png"))
    checks = [] if args.no_check else run_presets(cases, args.work, args.threads, args.results)
    elapsed = time.time() - t0
    load_after = uptime()
    if not rows and os.path.exists(os.path.join(args.results, "runs.csv")):
        rows = load_rows(os.path.join(args.results, "runs.csv"))
        load_before = load_before + " (presets stage; the sweep's runs.csv is reused)"
    if rows:
        write_summary(rows, args.results, info, command, load_before, load_after, elapsed, checks)
        with open(os.path.join(args.results, "machine.json"), "w") as f:
            json.dump(dict(info, load_before=load_before, load_after=load_after,
                           elapsed_s=round(elapsed, 1), command=command), f, indent=1)
    print("results in %s (%.0f s)" % (args.results, elapsed))
    if any(c["analytic"] and c["quality"] == "final" and not c["pass"] for c in checks):
        print("some analytic cases miss their tolerance at --quality final")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
