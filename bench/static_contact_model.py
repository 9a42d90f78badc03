#!/usr/bin/python3
"""What the grid collision takes from water at rest around a fixed box, one
step, without running the solver.

    bench/static_contact_model.py [--offset S] [--k K] [--by-normal]

The box and water of bench/study_fixed_box.py (box 0.1 m, dx 0.025 m, water
0.3 m deep, the box moved up by S cells), the water's particles on the
domain's lattice (K per cell and axis) with the hydrostatic pressure
rho g (0.3 - y), the box's samples on the domain's lattice every dx / 2 (as Triad samples
solids: at offsets that are not a multiple of half a cell they span a
little more or less than the box). Each node's force is the
MLS-MPM one, sum of V p (4 / dx^2) (x_i - x_p) w_ip, less its water's weight.
The contact nodes are those the box's samples reach, each with the normal of
the box's distance (outside: towards the nearest point; inside or on it: the
nearest faces' normals, averaged where several are equally near). Prints
the force the box takes when each contact node stops only the approaching
normal part of its force (frictionless, the default contact) and when it
stops all of it (sticky), against rho g V.
"""
import argparse

import numpy as np

DX, RHO, G = 0.025, 1000.0, 9.81


def weight(r):
    r = np.abs(r)
    return np.where(r < 0.5, 0.75 - r * r, np.where(r < 1.5, 0.5 * (1.5 - r) ** 2, 0.0))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--offset", type=float, default=0.0)
    ap.add_argument("--k", type=int, default=2)
    ap.add_argument("--by-normal", action="store_true")
    a = ap.parse_args()
    h = DX / a.k
    lo = np.array([0.15, 0.1 + a.offset * DX, 0.15])
    hi = lo + 0.1
    axes = [np.arange(h / 2, 0.4, h), np.arange(h / 2, 0.3, h), np.arange(h / 2, 0.4, h)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    x = x[~np.all((x >= lo) & (x < hi), 1)]
    p = RHO * G * (0.3 - x[:, 1])
    vol = h ** 3
    dims = np.array([17, 14, 17])
    f = np.zeros((*dims, 3))
    mass = np.zeros(dims)
    base = np.floor(x / DX - 0.5).astype(int)
    for o in np.ndindex(3, 3, 3):
        node = base + np.array(o)
        r = (node * DX - x) / DX
        w = weight(r[:, 0]) * weight(r[:, 1]) * weight(r[:, 2])
        ok = np.all((node >= 0) & (node < dims), 1)
        idx = tuple(node[ok].T)
        for d in range(3):
            np.add.at(f[..., d], idx, (vol * p * (4 / DX) * r[:, d] * w)[ok])
        np.add.at(mass, idx, (RHO * vol * w)[ok])
    f[..., 1] -= mass * G
    # The nodes the box's samples reach.
    hs = DX / 2
    s = np.stack(np.meshgrid(*[np.arange(hs / 2, 0.4, hs)] * 3, indexing="ij"), -1).reshape(-1, 3)
    s = s[np.all((s >= lo) & (s < hi), 1)]
    reach = np.zeros(dims, bool)
    sb = np.floor(s / DX - 0.5).astype(int)
    for o in np.ndindex(3, 3, 3):
        reach[tuple((sb + np.array(o)).T)] = True

    def normal(q):
        c = np.clip(q, lo, hi)
        if np.linalg.norm(q - c) > 1e-9:
            return (q - c) / np.linalg.norm(q - c)
        dl, dh = q - lo, hi - q
        dm = np.minimum(dl, dh)
        n = np.zeros(3)
        for d in range(3):
            if dm[d] <= dm.min() + 1e-9:
                n[d] = -1.0 if dl[d] < dh[d] else 1.0
        return n / np.linalg.norm(n)

    taken, sticky, groups = np.zeros(3), np.zeros(3), {}
    for node in np.argwhere(reach & (mass > 0)):
        fv = f[tuple(node)]
        n = normal(node * DX)
        fn = fv @ n
        t = fn * n if fn < 0 else np.zeros(3)
        taken += t
        sticky += fv
        g = groups.setdefault(tuple(np.round(n, 2)), [0, np.zeros(3), np.zeros(3)])
        g[0] += 1
        g[1] += fv
        g[2] += t
    exact = RHO * G * 1e-3
    print("offset %.3f cells, %d particles per cell: frictionless %.3f N (%+.1f%%), sticky %.3f N "
          "(%+.1f%%), rho g V %.3f N" % (a.offset, a.k ** 3, taken[1], 100 * (taken[1] / exact - 1),
                                         sticky[1], 100 * (sticky[1] / exact - 1), exact))
    if a.by_normal:
        for n, (count, fs, ts) in sorted(groups.items()):
            print("  normal %-22s %3d nodes: their forces %-28s taken %s"
                  % (n, count, np.round(fs, 3), np.round(ts, 3)))


if __name__ == "__main__":
    main()
