"""What the client checks share: a reader of the cache's PLY files written
here with numpy (it shares no code with Triad's writers, nor with the
Blender add-on it checks), and the list of failed checks."""
import numpy as np

failures = []


def check(ok, what):
    """Records a failed check (and prints it); the script exits 1 at the end."""
    if not ok:
        failures.append(what)
        print("FAIL:", what)


def exit_status():
    return 1 if failures else 0


def read_ply(path):
    """A binary little-endian PLY of scalar vertex properties and
    `list uchar int` faces (what Triad writes): {"vertex": structured array,
    "faces": (n, 3) int array, present when the file has faces}."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline()
            check(bool(line), f"{path}: no end_header")
            line = line.decode("ascii").strip()
            header.append(line)
            if not line or line == "end_header":
                break
        data = f.read()
    types = {"float": "<f4", "int": "<i4", "uint": "<u4", "uchar": "u1"}
    elements, props = [], {}
    for line in header:
        w = line.split()
        if w and w[0] == "element":
            elements.append((w[1], int(w[2])))
            props[w[1]] = []
        elif w and w[0] == "property" and w[1] != "list":
            props[elements[-1][0]].append((w[2], types[w[1]]))
    out, at = {}, 0
    for name, count in elements:
        if name == "vertex":
            dt = np.dtype(props["vertex"])
            out["vertex"] = np.frombuffer(data, dt, count, at)
            at += dt.itemsize * count
        elif name == "face":
            dt = np.dtype([("n", "u1"), ("v", "<i4", 3)])
            faces = np.frombuffer(data, dt, count, at)
            check(bool(np.all(faces["n"] == 3)), f"{path}: faces not triangles")
            out["faces"] = faces["v"]
            at += dt.itemsize * count
    return out
