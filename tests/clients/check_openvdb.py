#!/usr/bin/python3
"""Reads a Triad cache's volumes back with pyopenvdb (Debian's
python3-openvdb, OpenVDB's own reader) and checks them against the PLY
particles, read here with numpy: the grids a renderer looks for by name
(`density`, `vel`, `surface`) and their classes, the mass and momentum the
splat holds, and a `surface` that is a narrow band of distance.
Usage: check_openvdb.py CACHE_DIR SCENE.json"""
import json
import os
import sys

import numpy as np
import pyopenvdb as vdb

from cache_files import check, exit_status, read_ply

def on_values(grid):
    """Active values as an array (tiles counted by their voxel count)."""
    values, counts = [], []
    for item in grid.citerOnValues():
        lo, hi = item.min, item.max
        values.append(item.value)
        counts.append((hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1))
    return np.array(values, dtype=np.float64), np.array(counts, dtype=np.float64)


def main():
    cache, scene_path = sys.argv[1], sys.argv[2]
    scene = json.load(open(scene_path))
    objects = scene["objects"]
    rho = {k: m["density"] for k, m in scene["materials"].items()}
    # Every particle of an object carries its material's density times the
    # sampling cell's volume (dx^3 over the particles per cell).
    ppc = scene.get("solver", {}).get("particles_per_cell", 8)
    cell = scene["domain"]["dx"] ** 3 / ppc
    particle_mass = {k: rho[o["material"]] * cell for k, o in enumerate(objects) if o["kind"] == "mpm"}

    for frame in range(scene["frames"]["count"] + 1):
        path = os.path.join(cache, "volumes", f"density.{frame:04d}.vdb")
        grids = {g.name: g for g in vdb.readAll(path)[0]}
        check(sorted(grids) == ["density", "surface", "vel"], f"{path}: grids {sorted(grids)}")
        density, vel, surface = grids["density"], grids["vel"], grids["surface"]
        check(density.gridClass == vdb.GridClass.FOG_VOLUME, f"{path}: density class")
        check(surface.gridClass == vdb.GridClass.LEVEL_SET, f"{path}: surface class")
        check(vel.vectorType == vdb.VectorType.CONTRAVARIANT_RELATIVE, f"{path}: vel vector type")
        check(density["units"] == "kg/m^3" and vel["units"] == "m/s", f"{path}: units")
        check(density["frame"] == frame, f"{path}: frame metadata")

        # The splat holds the particles' mass and momentum.
        h = density.transform.voxelSize()[0]
        p = read_ply(os.path.join(cache, "particles", f"particles.{frame:04d}.ply"))["vertex"]
        m = np.zeros(len(p))
        for k, pm in particle_mass.items():
            m[p["object"] == k] = pm
        rho_v, n_v = on_values(density)
        grid_mass = float((rho_v * n_v).sum()) * h ** 3
        check(abs(grid_mass / m.sum() - 1) < 1e-4, f"{path}: mass {grid_mass} against {m.sum()}")
        d_acc, v_acc = density.getConstAccessor(), vel.getConstAccessor()
        momentum = np.zeros(3)
        for item in vel.citerOnValues():
            momentum += np.array(item.value) * d_acc.getValue(item.min) * h ** 3
        want = np.array([(m * p[c]).sum() for c in ("vx", "vy", "vz")])
        scale = float((m * np.sqrt(p["vx"] ** 2 + p["vy"] ** 2 + p["vz"] ** 2)).sum()) + 1e-9
        check(np.abs(momentum - want).max() < 1e-3 * scale + 1e-9,
              f"{path}: momentum {momentum} against {want}")

        # The level set is a band of distance: inactive at minus its half
        # width deep inside the water, about -1 voxel a voxel in from the top.
        if frame == 0:
            hs = surface.transform.voxelSize()[0]
            acc = surface.getConstAccessor()
            deep = surface.transform.worldToIndexNodeCentered((0.15, 0.05, 0.2))
            value, active = acc.probeValue(deep)
            check(not active and abs(value + 3 * hs) < 1e-6,
                  f"{path}: surface at the water's centre {value} (active {active}), "
                  f"expected inactive at {-3 * hs}")
            top = 0.1 + 0.0026  # the spheres' surface over the block's top face
            a = acc.getValue(surface.transform.worldToIndexNodeCentered((0.15, top - 1.0 * hs, 0.2)))
            b = acc.getValue(surface.transform.worldToIndexNodeCentered((0.15, top - 2.0 * hs, 0.2)))
            check(abs((a - b) / hs - 1) < 0.15, f"{path}: slope {(a - b) / hs} inside the band")
            print(f"surface: {surface.activeVoxelCount()} active voxels, slope {(a - b) / hs:.3f}")
    print(f"volumes of {scene['frames']['count'] + 1} frames read back")
    sys.exit(exit_status())


main()
