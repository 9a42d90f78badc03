"""Triad cache loader for Blender 3.4 and newer.

Install it as an add-on (Edit > Preferences > Add-ons > Install..., then
File > Import > Triad cache), or run it headless:

    blender -b --python tools/blender/triad_blender.py -- --cache DIR --save FILE.blend

It loads a whole cache under one empty, "Triad NAME", that turns Triad's
Y-up world into Blender's Z-up one (a rotation of +90 degrees about X: a
cache point (x, y, z) is at (x, -z, y) in Blender):

- the VDB sequence as a Volume whose frame k is the cache's frame k, its
  velocity grid `vel` in metres per second (motion blur), and a Principled
  Volume material whose density is the `density` grid over the densest
  material's density, so that water or sand reads as 1;
- the particles as a mesh of points whose positions and attributes
  (`velocity`, `id`, `object`, `J`) are read from the frame's PLY file on
  every frame change, in the cache's id order, with a Geometry Nodes
  modifier that makes them points of half a sampling spacing (Cycles
  renders them as spheres);
- the solids' (bodies/) and the materials' surface meshes (surfaces/),
  each a mesh object that takes its frame's PLY file on frame change;
- the scene's frame range (0..last frame written) and frame rate.

Frame changes are followed by a handler. The file saved by --save holds
this script as a registered text block, so a .blend opened with scripts
allowed (blender -y, or Preferences > Save & Load > Auto Run) plays the
cache back without the add-on installed.
"""

bl_info = {
    "name": "Triad cache",
    "author": "Triad",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > Triad cache",
    "description": "Load a Triad simulation cache: volumes, particles, solids, surfaces",
    "category": "Import-Export",
}

import json
import math
import os
import re
import sys

import bpy
import numpy as np
from bpy.app.handlers import persistent
from mathutils import Matrix, Vector

TEXT_NAME = "triad_blender.py"
# Triad is Y-up, Blender Z-up.
Y_UP_TO_Z_UP = Matrix.Rotation(math.pi / 2, 4, "X")


# Reading the cache

def read_ply(path):
    """A binary little-endian PLY file as written by Triad: a structured
    array of the vertex properties, and the triangles (n, 3) or None."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline()
            if not line:
                raise ValueError(f"{path}: no end_header")
            line = line.decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        data = f.read()
    types = {"float": "<f4", "int": "<i4", "uchar": "u1", "uint": "<u4"}
    elements, props = [], {}
    for line in header:
        w = line.split()
        if w[0] == "element":
            elements.append((w[1], int(w[2])))
            props[w[1]] = []
        elif w[0] == "property" and w[1] != "list":
            props[elements[-1][0]].append((w[2], types[w[1]]))
    vertices, faces, at = None, None, 0
    for name, count in elements:
        if name == "vertex":
            dt = np.dtype(props["vertex"])
            vertices = np.frombuffer(data, dt, count, at)
            at += dt.itemsize * count
        elif name == "face":
            dt = np.dtype([("n", "u1"), ("v", "<i4", 3)])
            faces = np.frombuffer(data, dt, count, at)["v"]
            at += dt.itemsize * count
    return vertices, faces


def frame_files(folder, stem=None):
    """{series name: {frame: path}} of NAME.FFFF.ply files in folder."""
    series = {}
    if not os.path.isdir(folder):
        return series
    for f in sorted(os.listdir(folder)):
        m = re.fullmatch(r"(.+)\.(\d{4,9})\.ply", f)
        if m and (stem is None or m.group(1) == stem):
            series.setdefault(m.group(1), {})[int(m.group(2))] = os.path.join(folder, f)
    return series


# Updating objects to a frame

def set_points(mesh, vertices):
    """The particles' mesh: one vertex per particle, with its attributes."""
    n = len(vertices)
    if len(mesh.vertices) != n:
        mesh.clear_geometry()
        mesh.vertices.add(n)
    co = np.stack([vertices["x"], vertices["y"], vertices["z"]], 1).astype(np.float32)
    mesh.vertices.foreach_set("co", co.ravel())
    attrs = {"velocity": ("FLOAT_VECTOR", "vector",
                          np.stack([vertices["vx"], vertices["vy"], vertices["vz"]], 1)),
             "id": ("INT", "value", vertices["id"]),
             "object": ("INT", "value", vertices["object"]),
             "J": ("FLOAT", "value", vertices["J"])}
    for name, (kind, field, values) in attrs.items():
        a = mesh.attributes.get(name)
        if a is None or a.data_type != kind or len(a.data) != n:
            if a is not None:
                mesh.attributes.remove(a)
            a = mesh.attributes.new(name, kind, "POINT")
        dtype = np.int32 if kind == "INT" else np.float32
        a.data.foreach_set(field, np.ascontiguousarray(values, dtype=dtype).ravel())
    mesh.update()


def set_triangles(mesh, vertices, faces):
    """A surface mesh: vertices and triangles, smooth shaded."""
    co = np.stack([vertices["x"], vertices["y"], vertices["z"]], 1).astype(np.float32)
    faces = faces if faces is not None else np.zeros((0, 3), np.int32)
    same = len(mesh.vertices) == len(co) and len(mesh.polygons) == len(faces)
    if same and len(faces):
        loops = np.empty(3 * len(faces), np.int32)
        mesh.loops.foreach_get("vertex_index", loops)
        same = np.array_equal(loops, faces.ravel())
    if not same:
        mesh.clear_geometry()
        mesh.vertices.add(len(co))
        mesh.loops.add(3 * len(faces))
        mesh.polygons.add(len(faces))
        mesh.loops.foreach_set("vertex_index", faces.astype(np.int32).ravel())
        mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * len(faces), 3, dtype=np.int32))
        mesh.polygons.foreach_set("loop_total", np.full(len(faces), 3, np.int32))
        if hasattr(mesh.polygons, "foreach_set") and len(faces):
            try:
                mesh.polygons.foreach_set("use_smooth", np.ones(len(faces), bool))
            except (AttributeError, TypeError):
                pass  # Blender 4.1 and newer shade from the mesh's own attribute
    mesh.vertices.foreach_set("co", co.ravel())
    mesh.update()


def update_object(obj, frame):
    """Gives a cache object the PLY file of `frame` (the last frame written
    past the end, the first before the start)."""
    folder, stem = obj["triad_dir"], obj["triad_stem"]
    last = int(obj["triad_last"])
    frame = min(max(int(frame), 0), last)
    if obj.get("triad_frame") == frame:
        return
    path = os.path.join(folder, f"{stem}.{frame:04d}.ply")
    if not os.path.exists(path):
        return
    vertices, faces = read_ply(path)
    if obj["triad_kind"] == "particles":
        set_points(obj.data, vertices)
    else:
        set_triangles(obj.data, vertices, faces)
    obj["triad_frame"] = frame


@persistent
def triad_frame_change(scene, depsgraph=None):
    for obj in scene.objects:
        if "triad_kind" in obj and obj.type == "MESH":
            update_object(obj, scene.frame_current)


def install_handler():
    handlers = bpy.app.handlers.frame_change_pre
    for h in list(handlers):
        if getattr(h, "__name__", "") == "triad_frame_change":
            handlers.remove(h)
    handlers.append(triad_frame_change)


# Building the scene

def points_modifier(obj, radius):
    """Geometry Nodes: the mesh's vertices as points of `radius`."""
    tree = bpy.data.node_groups.new("Triad points", "GeometryNodeTree")
    if hasattr(tree, "interface"):  # Blender 4.0 and newer
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        tree.inputs.new("NodeSocketGeometry", "Geometry")
        tree.outputs.new("NodeSocketGeometry", "Geometry")
    nodes, links = tree.nodes, tree.links
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    to_points = nodes.new("GeometryNodeMeshToPoints")
    to_points.inputs["Radius"].default_value = radius
    links.new(gin.outputs["Geometry"], to_points.inputs["Mesh"])
    links.new(to_points.outputs["Points"], gout.inputs["Geometry"])
    mod = obj.modifiers.new("Triad points", "NODES")
    mod.node_group = tree


def volume_material(name, density_scale):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    vol = nodes.new("ShaderNodeVolumePrincipled")
    vol.inputs["Density"].default_value = density_scale
    vol.inputs["Density Attribute"].default_value = "density"
    mat.node_tree.links.new(vol.outputs["Volume"], out.inputs["Volume"])
    return mat


def mesh_object(name, kind, folder, stem, last, parent, collection):
    obj = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    obj["triad_kind"], obj["triad_dir"], obj["triad_stem"] = kind, folder, stem
    obj["triad_last"] = last
    obj.parent = parent
    collection.objects.link(obj)
    return obj


def add_camera(run, root, collection):
    """A camera and a sun framing the domain from the front, above."""
    lo = Vector(run.get("domain", {}).get("min", (0, 0, 0)))
    hi = Vector(run.get("domain", {}).get("max", (1, 1, 1)))
    centre = root.matrix_world @ ((lo + hi) / 2)
    size = (hi - lo).length
    cam = bpy.data.objects.new("Triad camera", bpy.data.cameras.new("Triad camera"))
    cam.location = centre + Vector((0.35, -1.1, 0.55)).normalized() * 1.6 * size
    cam.rotation_euler = (centre - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.clip_end = 100 * size
    collection.objects.link(cam)
    sun = bpy.data.objects.new("Triad sun", bpy.data.lights.new("Triad sun", "SUN"))
    sun.rotation_euler = (math.radians(40), 0, math.radians(30))
    collection.objects.link(sun)
    return cam


def load_cache(cache, scene=None, camera=True):
    """Loads the cache at `cache` into `scene` (the current one). Returns
    the root empty."""
    scene = scene or bpy.context.scene
    cache = os.path.abspath(cache)
    run_path = os.path.join(cache, "run.json")
    if not os.path.exists(run_path):
        raise FileNotFoundError(f"{cache}: no run.json (not a Triad cache)")
    run = json.load(open(run_path))
    name = run.get("scene", {}).get("name", os.path.basename(cache))
    frames = run.get("frames", {})
    last = max(int(frames.get("written", 1)) - 1, 0)
    fps = float(frames.get("fps", 24.0))

    # Frame range and rate: frame k of Blender is frame k of the cache.
    scene.frame_start, scene.frame_end = 0, last
    scene.render.fps = max(1, round(fps))
    scene.render.fps_base = scene.render.fps / fps

    collection = bpy.data.collections.new(f"Triad {name}")
    scene.collection.children.link(collection)
    root = bpy.data.objects.new(f"Triad {name}", None)
    root.matrix_world = Y_UP_TO_Z_UP
    root["triad_cache"] = cache
    collection.objects.link(root)

    # Volumes: the VDB sequence, frame k on frame k, velocity in m/s.
    first = os.path.join(cache, "volumes", "density.0000.vdb")
    if os.path.exists(first):
        vol = bpy.data.volumes.new(f"{name} volumes")
        vol.filepath = first
        vol.is_sequence = True
        vol.frame_duration = last + 1
        vol.frame_start = 0
        vol.frame_offset = -1  # file numbers count from 0, Blender's from 1
        vol.sequence_mode = "CLIP"
        vol.grids.load()  # the velocity grid is named among the loaded ones
        vol.velocity_grid = "vel"
        vol.velocity_unit = "SECOND"
        densest = max([m.get("density", 1000.0) for m in run.get("materials", {}).values()] or [1000.0])
        vol.materials.append(volume_material(f"{name} density", 1.0 / densest))
        obj = bpy.data.objects.new(f"{name} volumes", vol)
        obj.parent = root
        collection.objects.link(obj)

    # Particles, solids and surfaces: meshes that follow their PLY files.
    particles = frame_files(os.path.join(cache, "particles"), "particles")
    if particles:
        obj = mesh_object(f"{name} particles", "particles", os.path.join(cache, "particles"),
                          "particles", last, root, collection)
        dx = float(run.get("quality", {}).get("dx", 0.02))
        ppc = float(run.get("quality", {}).get("particles_per_cell", 8))
        points_modifier(obj, 0.5 * dx / ppc ** (1.0 / 3.0))
    for folder, kind in (("bodies", "body"), ("surfaces", "surface")):
        for stem in frame_files(os.path.join(cache, folder)):
            label = stem if kind == "body" else f"{stem} surface"
            mesh_object(label, kind, os.path.join(cache, folder), stem, last, root, collection)

    if camera and scene.camera is None:
        scene.camera = add_camera(run, root, collection)
    install_handler()
    triad_frame_change(scene)
    return root


def embed_self():
    """Keeps this script in the .blend as a registered text block, so the
    saved file follows frame changes when opened with scripts allowed."""
    text = bpy.data.texts.get(TEXT_NAME) or bpy.data.texts.new(TEXT_NAME)
    text.from_string(open(__file__).read())
    text.use_module = True


# The add-on: File > Import > Triad cache

class IMPORT_OT_triad_cache(bpy.types.Operator):
    """Load a Triad cache folder (the one holding run.json)"""
    bl_idname = "import_scene.triad_cache"
    bl_label = "Triad cache"
    directory: bpy.props.StringProperty(subtype="DIR_PATH")

    def execute(self, context):
        try:
            load_cache(self.directory, context.scene)
        except (OSError, ValueError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}


def menu_import(self, context):
    self.layout.operator(IMPORT_OT_triad_cache.bl_idname, text="Triad cache (run.json folder)")


def register():
    bpy.utils.register_class(IMPORT_OT_triad_cache)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)
    install_handler()


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    bpy.utils.unregister_class(IMPORT_OT_triad_cache)
    for h in list(bpy.app.handlers.frame_change_pre):
        if getattr(h, "__name__", "") == "triad_frame_change":
            bpy.app.handlers.frame_change_pre.remove(h)


def main(argv):
    import argparse
    p = argparse.ArgumentParser(prog="blender -b --python triad_blender.py --")
    p.add_argument("--cache", required=True, help="the cache folder (holding run.json)")
    p.add_argument("--save", help="write the scene to this .blend file")
    args = p.parse_args(argv)
    # Start from an empty scene: the default cube would sit in the shot.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        load_cache(args.cache)
    except (OSError, ValueError) as e:
        print(f"triad_blender: error: {e}", file=sys.stderr)
        sys.exit(2)
    if args.save:
        embed_self()
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save))
        print(f"triad_blender: saved {args.save}")


if __name__ == "__main__" and "--" in sys.argv and "--cache" in sys.argv:
    main(sys.argv[sys.argv.index("--") + 1:])
else:
    # Run as the registered text block of a saved .blend (or imported as the
    # add-on, whose register() installs the same handler again).
    install_handler()
