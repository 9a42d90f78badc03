#!/usr/bin/python3
"""A floating log's righting moment: a rigid prism of rectangular section,
tilted about its long axis, in water at rest, against hydrostatics.

A square log of density ratio s floats flat only for s < 0.211 or s > 0.789;
in between its metacentric height a/(12 s) - a (1 - s)/2 is negative, flat
is unstable and it turns corner-down (45 degrees). A wide plank is stable
flat. The water is placed around the tilted body (columns of boxes cut at
its faces, level at H), the body's centre at the height where it displaces
its own weight, so that only the moment is out of balance.

  study_tilt.py --ratio 0.5 --tilt 10 --width 0.2 --height 0.2 [--fixed]
                [--quasi2d] [--time 2.5] [--solver '{"contact_gap": false}']

Free: prints the tilt every 0.25 s (degrees, from the body's quaternion).
Fixed: prints the mean force and torque over the second half of the run
against rho g V and the hydrostatic moment about the body's centre.
--glide V (m/s): the body is an animated collider moving along x at V
from rest (its animation keeps it spanning a quasi-2D tank); prints the
mean forces as --fixed does, fx among them (the water's drag).
Runs `build/app/triad` at one thread; the scene and cache go to --out.
"""
import argparse
import csv
import json
import math
import os
import subprocess

ap = argparse.ArgumentParser()
ap.add_argument("--ratio", type=float, default=0.5)
ap.add_argument("--tilt", type=float, default=10.0, help="degrees about z")
ap.add_argument("--width", type=float, default=0.2)
ap.add_argument("--height", type=float, default=0.2)
ap.add_argument("--dx", type=float, default=0.02)
ap.add_argument("--time", type=float, default=2.5)
ap.add_argument("--fixed", action="store_true")
ap.add_argument("--depth", type=float, default=None,
                help="the centre this far below the water level (m) instead of where the "
                     "body displaces its weight")
ap.add_argument("--quasi2d", action="store_true",
                help="domain 4 cells thick in z, the prism spanning it wall to wall")
ap.add_argument("--sides", type=int, default=4,
                help="4: a rectangle w x h; more: a regular polygon inscribed in the ellipse "
                     "w x h (32 for a round log)")
ap.add_argument("--thickness", type=float, default=None,
                help="the quasi-2D tank's thickness (m; 4 dx unless given)")
ap.add_argument("--glide", type=float, default=None,
                help="an animated collider moving along x at this speed (m/s) instead")
ap.add_argument("--bulk-modulus", type=float, default=2e5, help="the water's (Pa)")
ap.add_argument("--solver", default="{}", help="solver keys to add, as JSON")
ap.add_argument("--out", default="/tmp/study_tilt")
ap.add_argument("--triad", default=os.path.join(os.path.dirname(__file__), "..", "build", "app",
                                                "triad"))
a = ap.parse_args()

dx, w, h, s = a.dx, a.width, a.height, a.ratio
W, H = max(0.6, 4 * max(w, h)), 0.3  # tank length, water level
q2d = a.thickness or 4 * dx
D, L = (q2d, q2d) if a.quasi2d else (0.4, 0.3)
xc, zc = W / 2, D / 2
t = math.radians(a.tilt)


if a.sides == 4:
    outline = [(w / 2, h / 2), (-w / 2, h / 2), (-w / 2, -h / 2), (w / 2, -h / 2)]
else:
    outline = [(w / 2 * math.cos(2 * math.pi * k / a.sides), h / 2 * math.sin(2 * math.pi * k / a.sides))
               for k in range(a.sides)]


def section(yc):
    return [(xc + x * math.cos(t) - y * math.sin(t), yc + x * math.sin(t) + y * math.cos(t))
            for x, y in outline]


def below(poly, level):
    """The part of a convex polygon under y = level."""
    out = []
    for i in range(len(poly)):
        p, q = poly[i], poly[(i + 1) % len(poly)]
        if p[1] <= level:
            out.append(p)
        if (p[1] <= level) != (q[1] <= level):
            u = (level - p[1]) / (q[1] - p[1])
            out.append((p[0] + u * (q[0] - p[0]), level))
    return out


def area_centroid(poly):
    ar = cx = 0.0
    for i in range(len(poly)):
        (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % len(poly)]
        cr = x0 * y1 - x1 * y0
        ar += cr / 2
        cx += (x0 + x1) * cr / 6
    return ar, (cx / ar if ar else xc)


area0 = abs(area_centroid(outline)[0])  # for the weight: the polygon's, not the ellipse's
# The centre's height at which the body displaces its weight (bisection).
lo, hi = H - (w + h), H + (w + h)
for _ in range(60):
    yc = 0.5 * (lo + hi)
    if area_centroid(below(section(yc), H))[0] > s * area0:
        lo = yc
    else:
        hi = yc
if a.depth is not None:
    yc = H - a.depth
poly = section(yc)
sub, xb = area_centroid(below(poly, H))
buoyancy = 1000 * 9.81 * sub * L
moment = buoyancy * (xb - xc)


def span(x):
    ys = []
    for i in range(len(poly)):
        (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % len(poly)]
        if (x0 - x) * (x1 - x) <= 0 and x0 != x1:
            ys.append(y0 + (y1 - y0) * (x - x0) / (x1 - x0))
    return (min(ys), max(ys)) if ys else None


os.makedirs(a.out, exist_ok=True)
mesh = os.path.abspath(os.path.join(a.out, "prism.obj"))
with open(mesh, "w") as f:
    # The outline (counter-clockwise) extruded along z: vertex 2k + 1 at
    # -L/2, 2k + 2 at +L/2; sides, then fans for the two caps.
    n = len(outline)
    ccw = outline if area_centroid(outline)[0] > 0 else outline[::-1]
    for x, y in ccw:
        f.write(f"v {x} {y} {-L / 2}\nv {x} {y} {L / 2}\n")
    for k in range(n):
        a0, a1 = 2 * k + 1, 2 * ((k + 1) % n) + 1
        f.write(f"f {a0} {a1} {a1 + 1}\nf {a0} {a1 + 1} {a0 + 1}\n")
    for k in range(1, n - 1):
        f.write(f"f 1 {2 * (k + 1) + 1} {2 * k + 1}\nf 2 {2 * k + 2} {2 * (k + 1) + 2}\n")
objects = []


def water(name, lo, hi):
    objects.append({"name": name, "kind": "mpm", "material": "water",
                    "shape": {"box": {"min": lo, "max": hi}}})


if L < D:
    water("end0", [0, 0, 0], [W, H, zc - L / 2])
    water("end1", [0, 0, zc + L / 2], [W, H, D])
solver = {"cfl": 0.4, "max_dt": 0.002, "particles_per_cell": 8}
solver.update(json.loads(a.solver))
# Columns one particle spacing wide (dx/2 at 8 per cell), cut where the
# column's middle meets the body: each holds one column of particles.
step = dx / round(solver["particles_per_cell"] ** (1 / 3))
for i in range(int(round(W / step))):
    x0, x1 = i * step, (i + 1) * step
    sp = span(0.5 * (x0 + x1))
    if sp is None:
        water(f"c{i}", [x0, 0, zc - L / 2], [x1, H, zc + L / 2])
        continue
    if sp[0] > 0:
        water(f"b{i}", [x0, 0, zc - L / 2], [x1, min(sp[0], H), zc + L / 2])
    if sp[1] < H:
        water(f"t{i}", [x0, sp[1], zc - L / 2], [x1, H, zc + L / 2])
body = {"name": "prism", "kind": "rigid", "density": 1000 * s,
        "shape": {"mesh": {"path": mesh, "translate": [xc, yc, zc], "rotate_deg": [0, 0, a.tilt]}}}
if a.fixed:
    body["fixed"] = True
if a.glide is not None:
    del body["density"]
    body["kind"] = "collider"
    body["animation"] = {"keys": [{"time": 0, "translate": [0, 0, 0]},
                                  {"time": a.time, "translate": [a.glide * a.time, 0, 0]}]}
frames = int(round(a.time * 24))
scene = {"version": 1, "name": "study_tilt", "frames": {"count": frames, "fps": 24},
         "domain": {"min": [0, 0, 0], "max": [W, H + max(w, h) + 0.1, D], "dx": dx,
                    "boundary": {"type": "slip", "friction": 0}},
         "solver": solver,
         "materials": {"water": {"model": "water", "density": 1000, "bulk_modulus": a.bulk_modulus,
                                 "viscosity": 0.001}},
         "objects": objects + [body], "output": {"vdb": False, "png": False}}
path = os.path.join(a.out, "scene.json")
with open(path, "w") as f:
    json.dump(scene, f, indent=1)
stability = ""
if a.sides == 4:
    d = s * h  # upright draft
    gm = w * w / (12 * d) - (h - d) / 2  # BM - BG
    stability = (f"upright metacentric height {gm * 1000:+.1f} mm "
                 f"({'stable' if gm > 0 else 'unstable'} flat); ")
print(f"prism {w} x {h} m, {a.sides} sides, ratio {s}, tilt {a.tilt} deg, centre {yc:.4f} m; "
      f"{stability}hydrostatic force {buoyancy:.3f} N, moment {moment:+.4f} N m")
env = dict(os.environ, OMP_WAIT_POLICY="passive")
cache = os.path.join(a.out, "cache")
subprocess.run([a.triad, "run", path, "--threads", "1", "--no-probe", "--quiet", "--out", cache],
               check=True, env=env)
if a.fixed or a.glide is not None:
    rows = list(csv.DictReader(open(os.path.join(cache, "bodies", "forces.csv"))))
    half = rows[len(rows) // 2:]
    fx = sum(float(r["fx"]) for r in half) / len(half)
    fy = sum(float(r["fy"]) for r in half) / len(half)
    tz = sum(float(r["tz"]) for r in half) / len(half)
    share = f" ({tz / moment:.1%})" if abs(moment) > 1e-6 else f" (hydrostatics: {moment:+.4f})"
    print(f"mean over the second half: fx {fx:+.3f} N, fy {fy:.3f} N ({fy / buoyancy:.1%} of "
          f"hydrostatics), tz {tz:+.4f} N m{share}")
else:
    rows = [r for r in csv.DictReader(open(os.path.join(cache, "bodies", "rigid_states.csv")))]
    line = []
    for r in rows[::6]:
        roll = a.tilt + math.degrees(2 * math.atan2(float(r["qz"]), float(r["qw"])))
        line.append(f"{float(r['time']):.2f}s {roll:.1f}")
    print("tilt (deg): " + ", ".join(line))
