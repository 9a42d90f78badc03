#!/usr/bin/python3
"""Reads a Triad cache's vtk/ folder back with VTK's own readers (Debian's
python3-vtk9) and checks it against the PLY caches, read here with numpy:
every series of vtk/cache.pvd at every frame's time, the particles' points
and attributes equal to the PLY particles', the solids' and surfaces'
meshes closed and outward, a material's surface bounding its volume.
Usage: check_vtk.py CACHE_DIR SCENE.json"""
import json
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

from cache_files import check, exit_status, read_ply

def read_vtp(path):
    r = vtk.vtkXMLPolyDataReader()
    r.SetFileName(path)
    r.Update()
    check(r.GetErrorCode() == 0, f"{path}: VTK reader error {r.GetErrorCode()}")
    return r.GetOutput()


def polys(pd):
    cells = pd.GetPolys()
    offsets = vtk_to_numpy(cells.GetOffsetsArray())
    conn = vtk_to_numpy(cells.GetConnectivityArray())
    check(bool(np.all(np.diff(offsets) == 3)), "polygons are not all triangles")
    return conn.reshape(-1, 3)


def closed_and_outward(points, tris, what):
    edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    directed = {tuple(e) for e in edges}
    check(len(directed) == len(edges), f"{what}: a directed edge used twice")
    check(all((b, a) in directed for a, b in directed), f"{what}: not closed")
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    volume = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
    check(volume > 0, f"{what}: wound inward (signed volume {volume})")
    return volume


def main():
    cache, scene_path = sys.argv[1], sys.argv[2]
    scene = json.load(open(scene_path))
    fps, count = scene["frames"]["fps"], scene["frames"]["count"]
    vtkdir = os.path.join(cache, "vtk")
    pvd = ET.parse(os.path.join(vtkdir, "cache.pvd")).getroot()
    check(pvd.get("type") == "Collection", "cache.pvd is not a VTK collection")
    entries = pvd.find("Collection").findall("DataSet")
    names = sorted({e.get("name") for e in entries})
    solids = [o["name"] for o in scene["objects"] if o["kind"] in ("rigid", "elastic", "collider")]
    materials = sorted({o["material"] for o in scene["objects"] if o["kind"] == "mpm"})
    expected = sorted(["particles"] + solids + ["surface " + m for m in materials])
    check(names == expected, f"cache.pvd series {names}, expected {expected}")
    check(len(entries) == len(expected) * (count + 1), f"cache.pvd has {len(entries)} entries")
    for e in entries:
        t = float(e.get("timestep"))
        frame = int(round(t * fps))
        check(abs(t - frame / fps) < 1e-9, f"{e.get('file')}: time {t} is no frame's")
        path = os.path.join(vtkdir, e.get("file"))
        pd = read_vtp(path)
        name = e.get("name")
        if name == "particles":
            ply = read_ply(os.path.join(cache, "particles", f"particles.{frame:04d}.ply"))["vertex"]
            n = pd.GetNumberOfPoints()
            check(n == len(ply) and pd.GetNumberOfVerts() == n, f"{path}: {n} points")
            x = vtk_to_numpy(pd.GetPoints().GetData())
            check(np.array_equal(x, np.stack([ply["x"], ply["y"], ply["z"]], 1)), f"{path}: points")
            a = pd.GetPointData()
            v = vtk_to_numpy(a.GetArray("velocity"))
            check(np.array_equal(v, np.stack([ply["vx"], ply["vy"], ply["vz"]], 1)), f"{path}: velocity")
            for key in ("id", "object", "J"):
                arr = a.GetArray(key)
                check(arr is not None and np.array_equal(vtk_to_numpy(arr), ply[key]), f"{path}: {key}")
            ids = vtk_to_numpy(a.GetArray("id"))
            check(bool(np.all(np.diff(ids.astype(np.int64)) > 0)), f"{path}: ids not increasing")
        else:
            if name.startswith("surface "):
                ply = read_ply(os.path.join(cache, "surfaces", f"{name[8:]}.{frame:04d}.ply"))
            else:
                ply = read_ply(os.path.join(cache, "bodies", f"{name}.{frame:04d}.ply"))
            x = vtk_to_numpy(pd.GetPoints().GetData()).astype(np.float64)
            tris = polys(pd)
            pv = ply["vertex"]
            check(np.array_equal(x, np.stack([pv["x"], pv["y"], pv["z"]], 1).astype(np.float64)),
                  f"{path}: points differ from the PLY's")
            check(np.array_equal(tris, ply["faces"]), f"{path}: triangles differ from the PLY's")
            volume = closed_and_outward(x, tris, path)
            # At frame 0 a material sampled from boxes alone, apart, bounds
            # their volume.
            material = name[8:] if name.startswith("surface ") else None
            shapes = [o.get("shape", {}) for o in scene["objects"]
                      if o["kind"] == "mpm" and o.get("material") == material]
            if frame == 0 and shapes and all("box" in sh for sh in shapes) and \
                    not any("emit" in o for o in scene["objects"]):
                block = sum(float(np.prod(np.subtract(sh["box"]["max"], sh["box"]["min"])))
                            for sh in shapes)
                check(abs(volume / block - 1) < 0.04, f"{path}: volume {volume}, boxes {block}")
                print(f"{name} at frame 0: {volume / block:.4f} of its boxes' volume")
    print(f"{len(entries)} VTK files of {len(expected)} series read back")
    sys.exit(exit_status())


main()
