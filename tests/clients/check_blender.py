"""Run inside Blender on a .blend that tools/blender/triad_blender.py saved:
    blender -b -y FILE.blend --python-exit-code 1 --python check_blender.py -- CACHE_DIR
Checks what a TD sees against the cache's own files, read here with numpy:
the particles' points and attributes at several frames (after the Y-up to
Z-up turn), the solids' meshes, the volume's grids and the file it shows on
each frame, the frame range and rate, and a small Workbench render that is
not empty."""
import json
import os
import sys

import bpy
import numpy as np

# The shared reader beside this script (Blender runs it with its own sys.path).
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cache_files import check, exit_status, read_ply  # noqa: E402

cache = sys.argv[sys.argv.index("--") + 1]
def world_points(obj):
    n = len(obj.data.vertices)
    co = np.empty(3 * n, np.float32)
    obj.data.vertices.foreach_get("co", co)
    m = np.array(obj.matrix_world)
    co = co.reshape(-1, 3).astype(np.float64)
    return co @ m[:3, :3].T + m[:3, 3]


def attribute(mesh, name, width, dtype):
    a = mesh.attributes[name]
    out = np.empty(len(a.data) * width, dtype)
    a.data.foreach_get("vector" if width == 3 else "value", out)
    return out.reshape(-1, width) if width == 3 else out


run = json.load(open(os.path.join(cache, "run.json")))
last = run["frames"]["written"] - 1
scene = bpy.context.scene
check(scene.frame_start == 0 and scene.frame_end == last, f"frame range {scene.frame_start}..{scene.frame_end}")
check(abs(scene.render.fps / scene.render.fps_base - run["frames"]["fps"]) < 1e-6, "frame rate")
objects = {o.name: o for o in scene.objects}
name = run["scene"]["name"]
particles = objects[f"{name} particles"]
volume = objects[f"{name} volumes"].data
check(volume.velocity_grid == "vel" and volume.velocity_unit == "SECOND", "velocity grid and unit")

for frame in sorted({0, 1, last}):
    scene.frame_set(frame)
    # Particles: Blender's point (x, -z, y) is the cache's (x, y, z).
    ply = read_ply(os.path.join(cache, "particles", f"particles.{frame:04d}.ply"))["vertex"]
    want = np.stack([ply["x"], -ply["z"], ply["y"]], 1).astype(np.float64)
    got = world_points(particles)
    check(got.shape == want.shape and np.abs(got - want).max() < 1e-6,
          f"frame {frame}: particle points differ from the cache's")
    mesh = particles.data
    check(np.array_equal(attribute(mesh, "id", 1, np.int32), ply["id"]), f"frame {frame}: id")
    check(np.array_equal(attribute(mesh, "object", 1, np.int32), ply["object"]), f"frame {frame}: object")
    check(np.array_equal(attribute(mesh, "J", 1, np.float32), ply["J"]), f"frame {frame}: J")
    v = np.stack([ply["vx"], ply["vy"], ply["vz"]], 1)
    check(np.array_equal(attribute(mesh, "velocity", 3, np.float32), v), f"frame {frame}: velocity")
    # Solids follow their files.
    for f in os.listdir(os.path.join(cache, "bodies")):
        if not f.endswith(f".{frame:04d}.ply"):
            continue
        body = read_ply(os.path.join(cache, "bodies", f))["vertex"]
        obj = objects[f.split(".")[0]]
        want = np.stack([body["x"], -body["z"], body["y"]], 1).astype(np.float64)
        check(np.abs(world_points(obj) - want).max() < 1e-6, f"frame {frame}: body {obj.name}")
    # The volume shows this frame's file, with its grids.
    volume.grids.load()
    check(os.path.basename(volume.grids.frame_filepath) == f"density.{frame:04d}.vdb",
          f"frame {frame}: volume shows {volume.grids.frame_filepath}")
    check(sorted(g.name for g in volume.grids) == ["density", "surface", "vel"],
          f"frame {frame}: grids {[g.name for g in volume.grids]}")

# A tiny Workbench render of the last frame is not empty.
scene.render.engine = "BLENDER_WORKBENCH"
scene.render.resolution_x, scene.render.resolution_y = 96, 54
scene.render.resolution_percentage = 100
out = os.path.join(cache, "blender_check.png")
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
img = bpy.data.images.load(out)
px = np.array(img.pixels[:]).reshape(-1, 4)[:, :3]
background = np.median(px[[0, 95, -96, -1]], axis=0)
drawn = float((np.abs(px - background).max(axis=1) > 0.05).mean())
print(f"render: {100 * drawn:.1f}% of the pixels drawn")
check(drawn > 0.02, f"render nearly empty ({100 * drawn:.1f}% drawn)")

print("blender check:", "FAILED" if exit_status() else "passed")
sys.exit(exit_status())
