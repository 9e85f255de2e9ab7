"""Imports each GLB into Blender (headless) and checks it arrived whole.

Run by Blender itself:
    blender --background --factory-startup --python tools/gltf/blender_import.py -- A.glb B.glb ...

Per file: a fresh empty scene, Blender's own glTF importer, then the imported meshes must hold
exactly the triangles the GLB's index accessors declare, every embedded image must have become a
Blender image with the GLB's pixel size, and the imported bounding box must span the POSITION
accessor's extent (glTF is y-up, Blender z-up: the extents are compared as sorted triples).
Exit status 1 on any failure, naming the file and what differed.
"""

import json
import struct
import sys

import bpy
import numpy
from mathutils import Vector

# Debian's Blender 3.4 glTF importer still uses `numpy.bool`, which NumPy 1.24 (the same
# distribution's) removed; the alias is the builtin it always meant.
if not hasattr(numpy, "bool"):
    numpy.bool = bool


def glb_json(path):
    """The JSON chunk of a GLB (the file's own declaration of what it holds)."""
    with open(path, "rb") as f:
        data = f.read()
    magic, version, _length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2:
        raise ValueError(f"{path}: not a glTF 2.0 binary")
    chunk_len, chunk_type = struct.unpack_from("<I4s", data, 12)
    if chunk_type != b"JSON":
        raise ValueError(f"{path}: first chunk is {chunk_type!r}, expected JSON")
    return json.loads(data[20 : 20 + chunk_len])


def declared(doc):
    """Triangles, image count and POSITION extent the GLB declares."""
    triangles, lo, hi = 0, [float("inf")] * 3, [float("-inf")] * 3
    for mesh in doc.get("meshes", []):
        for prim in mesh["primitives"]:
            if prim.get("mode", 4) != 4:
                raise ValueError("only triangle lists are expected")
            triangles += doc["accessors"][prim["indices"]]["count"] // 3
            pos = doc["accessors"][prim["attributes"]["POSITION"]]
            lo = [min(a, b) for a, b in zip(lo, pos["min"])]
            hi = [max(a, b) for a, b in zip(hi, pos["max"])]
    extent = sorted(h - l for h, l in zip(hi, lo))
    return triangles, len(doc.get("images", [])), extent


def imported():
    """Triangles, images and extent of what Blender imported."""
    triangles = 0
    lo, hi = [float("inf")] * 3, [float("-inf")] * 3
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH":
            continue
        mesh = obj.data
        mesh.calc_loop_triangles()
        triangles += len(mesh.loop_triangles)
        for corner in obj.bound_box:
            world = obj.matrix_world @ Vector(corner)
            lo = [min(a, b) for a, b in zip(lo, world)]
            hi = [max(a, b) for a, b in zip(hi, world)]
    images = [im for im in bpy.data.images if im.size[0] > 0]
    extent = sorted(h - l for h, l in zip(hi, lo))
    return triangles, images, extent


def check(path):
    doc = glb_json(path)
    want_tris, want_images, want_extent = declared(doc)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.import_scene.gltf(filepath=path)
    if result != {"FINISHED"}:
        return f"import returned {result}"
    tris, images, extent = imported()
    problems = []
    if tris != want_tris:
        problems.append(f"{tris} triangles imported, the GLB declares {want_tris}")
    if len(images) != want_images:
        problems.append(f"{len(images)} images imported, the GLB embeds {want_images}")
    for got, want in zip(extent, want_extent):
        if abs(got - want) > 1e-4 * max(1.0, want):
            problems.append(f"extent {extent} differs from the POSITION extent {want_extent}")
            break
    summary = f"{tris} triangles, {len(images)} image(s), extent " + " x ".join(
        f"{e:.3f}" for e in extent
    )
    return "; ".join(problems) if problems else ("ok", summary)


def main():
    paths = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    if not paths:
        print("usage: blender --background --python blender_import.py -- FILE.glb ...")
        sys.exit(2)
    failed = 0
    for path in paths:
        try:
            outcome = check(path)
        except Exception as e:  # the importer's own errors are findings, not crashes
            outcome = f"import failed: {e}"
        if isinstance(outcome, tuple):
            print(f"blender ok   {path}: {outcome[1]}")
        else:
            failed += 1
            print(f"blender FAIL {path}: {outcome}")
    print(f"{len(paths) - failed} of {len(paths)} GLB files imported into Blender {bpy.app.version_string}")
    sys.exit(1 if failed else 0)


main()
