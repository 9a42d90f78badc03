#!/usr/bin/python3
"""The force on a fixed box held under water, against Archimedes, as the box
moves within its cell.

    bench/study_fixed_box.py [--triad build/app/triad] [--ppc 8] [--shift S ...]
                             [--friction MU] [--viscosity ETA] [--frames N]
                             [--solver JSON]

The scene is the one of the forces test (tests/test_bodies_cli.cpp): a box
0.1 m on a side, fixed, in water 0.3 m deep (K = 1e5 Pa), dx = 0.025 m,
20 frames a second. The box is moved up by S cells and the water is built
around it as boxes. Water particles lie on the domain's lattice (spacing
dx / k for k^3 particles per cell), the box's samples on its half-cell
lattice: where S * k is not a whole number the box's faces (its distance
field, which gives the contact's normals) lie between lattice planes, up to
half a spacing from where the water's particles and the box's samples
meet; the line marks it 'faces off the lattice'. Prints each shift's mean
vertical force over the last ten frames and its error against
rho g V = 9.81 N.
"""
import argparse
import csv
import json
import os
import subprocess
import tempfile

DX = 0.025


def box(lo, hi):
    return {"box": {"min": list(lo), "max": list(hi)}}


def scene(shift, args):
    y0 = 0.1 + shift * DX
    y1, x0, x1, z0, z1 = y0 + 0.1, 0.15, 0.25, 0.15, 0.25
    water = [((0, 0, 0), (0.4, y0, 0.4)), ((0, y1, 0), (0.4, 0.3, 0.4)),
             ((0, y0, 0), (x0, y1, 0.4)), ((x1, y0, 0), (0.4, y1, 0.4)),
             ((x0, y0, 0), (x1, y1, z0)), ((x0, y0, z1), (x1, y1, 0.4))]
    solver = {"particles_per_cell": args.ppc}
    solver.update(json.loads(args.solver))
    j = {"version": 1, "name": "fixed_box",
         "domain": {"min": [0, 0, 0], "max": [0.4, 0.4, 0.4], "dx": DX},
         "frames": {"count": args.frames, "fps": 20}, "solver": solver,
         "materials": {"water": {"model": "water", "density": 1000, "bulk_modulus": 1e5,
                                 "viscosity": args.viscosity}},
         "objects": [{"name": "water%d" % k, "kind": "mpm", "material": "water",
                      "shape": box(*w)} for k, w in enumerate(water)],
         "output": {"ply": False, "vdb": False, "png": False}}
    j["objects"].append({"name": "box", "kind": "rigid", "density": 2000, "fixed": True,
                         "friction": args.friction, "shape": box((x0, y0, z0), (x1, y1, z1))})
    return j


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--triad", default="build/app/triad")
    ap.add_argument("--ppc", type=int, default=8)
    ap.add_argument("--shift", type=float, nargs="+", default=[0, 0.125, 0.25, 0.375, 0.5,
                                                                0.625, 0.75, 0.875])
    ap.add_argument("--friction", type=float, default=0.0)
    ap.add_argument("--viscosity", type=float, default=50.0)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--solver", default="{}")
    args = ap.parse_args()
    k = round(args.ppc ** (1 / 3))
    exact = 1000 * 9.81 * 1e-3
    with tempfile.TemporaryDirectory() as tmp:
        for s in args.shift:
            path = os.path.join(tmp, "scene.json")
            with open(path, "w") as f:
                json.dump(scene(s, args), f)
            out = os.path.join(tmp, "out")
            subprocess.run([args.triad, "run", path, "--out", out, "--no-probe"],
                           check=True, capture_output=True)
            with open(os.path.join(out, "bodies", "forces.csv")) as f:
                rows = list(csv.reader(f))[1:]
            fy = sum(float(r[4]) for r in rows[-10:]) / 10
            seeded = "" if abs(s * k - round(s * k)) < 1e-6 else "  (faces off the lattice)"
            print("shift %.3f cells: fy %.3f N, %+.1f%% against rho g V%s"
                  % (s, fy, 100 * (fy / exact - 1), seeded))


if __name__ == "__main__":
    main()
