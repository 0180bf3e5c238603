#!/usr/bin/env python3
"""Expected triangle counts and bounds of the valid glTF test models, computed independently of
the Rust loader (plain JSON + struct, no glTF library) for tests/artefact_data.rs.

Usage: python3 scripts/gltf_expected.py [DATA_DIR]   (default ../shared/data/gltf)

For each file: the default scene (else the first, else all root nodes), node matrices composed
(TRS or matrix), every TRIANGLES/STRIP/FAN primitive counted (indices or vertices / 3, or n - 2),
and the bounds of every float POSITION of those primitives transformed to the scene's space.
"""
import base64
import json
import math
import os
import struct
import sys
import urllib.parse

FILES = [
    "BoxTextured-glTF/BoxTextured.gltf",
    "BoxTextured-glTF-Binary/BoxTextured.glb",
    "BoxTextured-glTF-Embedded/BoxTextured.gltf",
    "BoxTextured-glTF-pbrSpecularGlossiness/BoxTextured.gltf",
    "BoxTexcoords-glTF/boxTexcoords.gltf",
    "BoxBadNormals-glTF-Binary/BoxBadNormals.glb",
    "2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
    "ClearCoat-glTF/ClearCoatTest.gltf",
    "textureTransform/TextureTransformTest.gltf",
    "glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf",
    "cameras/Cameras.gltf",
    "simple_skin/simple_skin.gltf",
    "issue_3269/texcoord_crash.gltf",
    "TestNoRootNode/NoScene.gltf",
    "TestNoRootNode/SceneWithoutNodes.gltf",
] + [f"glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_{i:02}.gltf" for i in range(16)]


def load(path):
    raw = open(path, "rb").read()
    if raw[:4] == b"glTF":
        jlen = struct.unpack_from("<I", raw, 12)[0]
        doc = json.loads(raw[20 : 20 + jlen])
        rest = raw[20 + jlen :]
        bin_chunk = rest[8 : 8 + struct.unpack_from("<I", rest, 0)[0]] if rest else None
        return doc, bin_chunk
    return json.loads(raw), None


def buffer_bytes(doc, i, folder, bin_chunk):
    b = doc["buffers"][i]
    uri = b.get("uri")
    if uri is None:
        return bin_chunk
    if uri.startswith("data:"):
        return base64.b64decode(uri.split(",", 1)[1])
    return open(os.path.join(folder, urllib.parse.unquote(uri)), "rb").read()


def matmul(a, b):  # column-major 4x4 as flat lists
    return [sum(a[k * 4 + r] * b[c * 4 + k] for k in range(4)) for c in range(4) for r in range(4)]


def local(node):
    if "matrix" in node:
        return list(node["matrix"])
    tx, ty, tz = node.get("translation", [0, 0, 0])
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    sx, sy, sz = node.get("scale", [1, 1, 1])
    r = [
        1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w), 0,
        2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w), 0,
        2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y), 0,
        0, 0, 0, 1,
    ]
    s = [sx, 0, 0, 0, 0, sy, 0, 0, 0, 0, sz, 0, 0, 0, 0, 1]
    t = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, tx, ty, tz, 1]
    return matmul(t, matmul(r, s))


def positions(doc, acc_index, folder, bin_chunk):
    acc = doc["accessors"][acc_index]
    assert acc["componentType"] == 5126 and acc["type"] == "VEC3"
    view = doc["bufferViews"][acc["bufferView"]]
    data = buffer_bytes(doc, view["buffer"], folder, bin_chunk)
    stride = view.get("byteStride", 12)
    base = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return [struct.unpack_from("<3f", data, base + i * stride) for i in range(acc["count"])]


def expected(path):
    doc, bin_chunk = load(path)
    folder = os.path.dirname(path)
    nodes = doc.get("nodes", [])
    scenes = doc.get("scenes", [])
    scene = doc.get("scene")
    if scene is not None and scene < len(scenes):
        roots = scenes[scene].get("nodes", [])
    elif scenes:
        roots = scenes[0].get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    tris = 0
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    stack = [(r, [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]) for r in roots]
    while stack:
        n, parent = stack.pop()
        world = matmul(parent, local(nodes[n]))
        if "mesh" in nodes[n]:
            for prim in doc["meshes"][nodes[n]["mesh"]]["primitives"]:
                mode = prim.get("mode", 4)
                if mode not in (4, 5, 6):
                    continue
                pos_acc = prim["attributes"]["POSITION"]
                count = doc["accessors"][prim["indices"]]["count"] if "indices" in prim else doc["accessors"][pos_acc]["count"]
                tris += count // 3 if mode == 4 else max(count - 2, 0)
                for p in positions(doc, pos_acc, folder, bin_chunk):
                    w = [sum(world[k * 4 + r] * (list(p) + [1])[k] for k in range(4)) for r in range(3)]
                    lo = [min(a, b) for a, b in zip(lo, w)]
                    hi = [max(a, b) for a, b in zip(hi, w)]
        for c in nodes[n].get("children", []):
            stack.append((c, world))
    if tris == 0:
        lo = hi = [0.0, 0.0, 0.0]
    return tris, lo, hi


def main():
    data = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "gltf")
    for f in FILES:
        tris, lo, hi = expected(os.path.join(data, f))
        def num(x):
            s = f"{x:.9g}"
            return s if any(c in s for c in ".e") else s + ".0"

        fmt = lambda v: "[" + ", ".join(num(x) for x in v) + "]"
        print(f'    ("{f}", {tris}, {fmt(lo)}, {fmt(hi)}),')


if __name__ == "__main__":
    main()
