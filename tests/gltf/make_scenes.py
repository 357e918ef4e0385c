#!/usr/bin/env python3
"""Writes the glTF test scenes of crates/lightpath/tests/gltf.rs (standard library only).

    python3 tests/gltf/make_scenes.py        # from the repository root

hierarchy.gltf  the scene with an external buffer (hierarchy.bin), the base colour and
                metallic-roughness textures as data: URIs, the normal map as an external
                file (normal.png)
hierarchy.glb   the same scene in a binary container, every image in a buffer view
defaults.gltf   one quad, no camera and no light (a data: URI buffer)
alpha.gltf      alpha modes: a quad cut out by an RGBA texture (MASK), a quad of constant
                alpha below its cutoff (MASK, invisible), one of alpha 0.3 with BLEND
                (stochastic transparency), and an opaque quad behind them all

The scene (glTF coordinates, +Y up): a root node (translated, turned 30 degrees about Y,
scaled 1.5) with two children that use the same cube mesh (u16 indices, normals, UVs,
a textured material); the second cube has a child, an emissive quad (non-indexed, a
matrix transform, emissive strength 4); a floor quad (u8 indices); a perspective camera;
a point light and a spot light.
"""

import base64
import json
import math
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def png(width, height, rows):
    """An 8-bit RGB PNG, or RGBA when the pixels have four channels; rows[y][x] =
    (r, g, b) or (r, g, b, a), row 0 at the top."""
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8,
                                         6 if len(rows[0][0]) == 4 else 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw))
            + chunk(b"IEND", b""))


# Base colour: top-left (255,128,0), top-right green, bottom-left blue, bottom-right white.
BASE_PNG = png(2, 2, [[(255, 128, 0), (0, 255, 0)], [(0, 0, 255), (255, 255, 255)]])
# Metallic-roughness: G (roughness) 128, B (metallic) 64 everywhere; R unused.
MR_PNG = png(2, 2, [[(7, 128, 64)] * 2] * 2)
# A flat tangent-space normal.
NORMAL_PNG = png(2, 2, [[(128, 128, 255)] * 2] * 2)


def quat(axis, degrees):
    h = math.radians(degrees) / 2
    n = math.sqrt(sum(a * a for a in axis))
    return [a / n * math.sin(h) for a in axis] + [math.cos(h)]


class Blob:
    def __init__(self):
        self.data = bytearray()
        self.views = []
        self.accessors = []

    def view(self, payload, target=None):
        while len(self.data) % 4:
            self.data.append(0)
        v = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(payload)}
        if target:
            v["target"] = target
        self.data += payload
        self.views.append(v)
        return len(self.views) - 1

    def accessor(self, fmt, kind, values, ctype, target, bounds=False):
        payload = b"".join(struct.pack("<" + fmt, *v) if isinstance(v, (list, tuple))
                           else struct.pack("<" + fmt, v) for v in values)
        a = {"bufferView": self.view(payload, target), "componentType": ctype,
             "count": len(values), "type": kind}
        if bounds:
            a["min"] = [min(v[i] for v in values) for i in range(3)]
            a["max"] = [max(v[i] for v in values) for i in range(3)]
        self.accessors.append(a)
        return len(self.accessors) - 1


FLOAT, U8, U16 = 5126, 5121, 5123
ARRAY, ELEMENTS = 34962, 34963


def cube():
    """24 vertices (4 a face), outward normals, counter-clockwise faces."""
    pos, nrm, uv, idx = [], [], [], []
    for axis in range(3):
        for sign in (1, -1):
            n = [0.0, 0.0, 0.0]
            n[axis] = float(sign)
            u = [0.0, 0.0, 0.0]
            u[(axis + 1) % 3] = 1.0
            v = [0.0, 0.0, 0.0]
            v[(axis + 2) % 3] = 1.0
            if sign < 0:
                u, v = v, u
            base = len(pos)
            for (a, b), t in zip([(-1, -1), (1, -1), (1, 1), (-1, 1)],
                                 [(0, 1), (1, 1), (1, 0), (0, 0)]):
                pos.append([0.5 * (n[i] + a * u[i] + b * v[i]) for i in range(3)])
                nrm.append(n)
                uv.append(list(t))
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    return pos, nrm, uv, idx


def scene(images_in_views, buffer_uri):
    blob = Blob()
    pos, nrm, uv, idx = cube()
    cube_prim = {
        "attributes": {
            "POSITION": blob.accessor("3f", "VEC3", pos, FLOAT, ARRAY, bounds=True),
            "NORMAL": blob.accessor("3f", "VEC3", nrm, FLOAT, ARRAY),
            "TEXCOORD_0": blob.accessor("2f", "VEC2", uv, FLOAT, ARRAY),
        },
        "indices": blob.accessor("H", "SCALAR", idx, U16, ELEMENTS),
        "material": 0,
    }
    floor_pos = [[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]]
    floor_prim = {
        "attributes": {"POSITION": blob.accessor("3f", "VEC3", floor_pos, FLOAT, ARRAY,
                                                 bounds=True)},
        "indices": blob.accessor("B", "SCALAR", [0, 1, 2, 0, 2, 3], U8, ELEMENTS),
        "material": 2,
    }
    q = [[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0]]
    lamp_pos = q + [[-0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]]
    lamp_prim = {
        "attributes": {"POSITION": blob.accessor("3f", "VEC3", lamp_pos, FLOAT, ARRAY,
                                                 bounds=True)},
        "material": 1,
    }
    pngs = [("base", BASE_PNG), ("metallic_roughness", MR_PNG), ("normal", NORMAL_PNG)]
    images = []
    for name, data in pngs:
        if images_in_views:
            images.append({"name": name, "bufferView": blob.view(data), "mimeType": "image/png"})
        elif name == "normal":
            images.append({"name": name, "uri": "normal.png"})
        else:
            images.append({"name": name, "uri": "data:image/png;base64,"
                           + base64.b64encode(data).decode()})
    doc = {
        "asset": {"version": "2.0", "generator": "lightpath tests/gltf/make_scenes.py"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": [0, 4, 5, 6, 7]}],
        "nodes": [
            {"name": "root", "translation": [0, 0.75, 0], "rotation": quat([0, 1, 0], 30),
             "scale": [1.5, 1.5, 1.5], "children": [1, 2]},
            {"name": "cubeA", "translation": [-0.6, 0, 0], "scale": [0.5, 0.5, 0.5],
             "mesh": 0},
            {"name": "cubeB", "translation": [0.6, 0.1, 0], "rotation": quat([1, 0, 0], -20),
             "scale": [0.4, 0.4, 0.4], "mesh": 0, "children": [3]},
            # Column-major: scale (0.8, 0.6, 1), then translation (0, 0, 0.8).
            {"name": "lamp", "matrix": [0.8, 0, 0, 0, 0, 0.6, 0, 0, 0, 0, 1, 0, 0, 0, 0.8, 1],
             "mesh": 2},
            {"name": "floor", "scale": [4, 1, 4], "mesh": 1},
            {"name": "camera", "translation": [0, 1.6, 5], "rotation": quat([1, 0, 0], -10),
             "camera": 0},
            {"name": "bulb", "translation": [2, 4, 3],
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "spot", "translation": [-2, 3, 0], "rotation": quat([1, 0, 0], -90),
             "extensions": {"KHR_lights_punctual": {"light": 1}}},
        ],
        "meshes": [
            {"name": "cube", "primitives": [cube_prim]},
            {"name": "floor", "primitives": [floor_prim]},
            {"name": "lamp", "primitives": [lamp_prim]},
        ],
        "materials": [
            {"name": "textured", "pbrMetallicRoughness": {
                "baseColorFactor": [0.9, 0.9, 0.9, 1],
                "baseColorTexture": {"index": 0},
                "metallicFactor": 0.8, "roughnessFactor": 0.6,
                "metallicRoughnessTexture": {"index": 1}},
             "normalTexture": {"index": 2, "scale": 1.0}},
            {"name": "glow", "pbrMetallicRoughness": {
                "baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0, "roughnessFactor": 1},
             "emissiveFactor": [1.0, 0.8, 0.5],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
            {"name": "floor", "pbrMetallicRoughness": {
                "baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0,
                "roughnessFactor": 0.9}},
        ],
        "textures": [{"source": 0, "sampler": 0}, {"source": 1}, {"source": 2}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
        "images": images,
        "cameras": [{"type": "perspective", "perspective": {
            "yfov": 0.6, "aspectRatio": 1.5, "znear": 0.1, "zfar": 100}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1, 1, 1], "intensity": 30},
            {"type": "spot", "color": [1, 0.9, 0.8], "intensity": 20,
             "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.6}},
        ]}},
        "accessors": blob.accessors,
        "bufferViews": blob.views,
        "buffers": [{"byteLength": len(blob.data)}],
    }
    if buffer_uri:
        doc["buffers"][0]["uri"] = buffer_uri
    return doc, bytes(blob.data)


def defaults_scene():
    """One quad facing +Z, no camera, no light; the buffer is a data: URI."""
    blob = Blob()
    quad = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]
    prim = {"attributes": {"POSITION": blob.accessor("3f", "VEC3", quad, FLOAT, ARRAY,
                                                     bounds=True)},
            "indices": blob.accessor("I", "SCALAR", [0, 1, 2, 0, 2, 3], 5125, ELEMENTS)}
    data = bytes(blob.data)
    return {
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [1, 2, 3]}],
        "meshes": [{"primitives": [prim]}],
        "accessors": blob.accessors,
        "bufferViews": blob.views,
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(data).decode()}],
    }


# Alpha (coverage) of the cut-out quad: its upper-left and lower-right quarters are
# below the cutoff 0.5 (0 and 64/255), the others above (255 and 191/255).
ALPHA_PNG = png(2, 2, [[(200, 30, 30, 0), (30, 200, 30, 255)],
                       [(30, 30, 200, 191), (200, 200, 200, 64)]])


def alpha_scene():
    """Quads facing +Z over x in [0, 1], [1, 2], [2, 3] (y in [0, 1], z = 0), and an
    opaque quad behind them over x in [0, 3] at z = -1; everything in one data: URI
    buffer, the texture a data: URI PNG with nearest filtering."""
    blob = Blob()

    def quad(x0, x1, z, uvs):
        pos = [[x0, 0, z], [x1, 0, z], [x1, 1, z], [x0, 1, z]]
        attributes = {"POSITION": blob.accessor("3f", "VEC3", pos, FLOAT, ARRAY, bounds=True)}
        if uvs:
            # glTF's v runs down the image: the image's top row is at y = 1.
            attributes["TEXCOORD_0"] = blob.accessor(
                "2f", "VEC2", [[(p[0] - x0) / (x1 - x0), 1 - p[1]] for p in pos], FLOAT,
                ARRAY)
        indices = blob.accessor("H", "SCALAR", [0, 1, 2, 0, 2, 3], U16, ELEMENTS)
        return {"attributes": attributes, "indices": indices}

    prims = [quad(0, 1, 0, True), quad(1, 2, 0, False), quad(2, 3, 0, False),
             quad(0, 3, -1, False)]
    for material, prim in enumerate(prims):
        prim["material"] = material
    data = bytes(blob.data)
    return {
        "asset": {"version": "2.0", "generator": "lightpath tests/gltf/make_scenes.py"},
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [{"name": name, "mesh": i}
                  for i, name in enumerate(["cutout", "hidden", "blend", "back"])],
        "meshes": [{"primitives": [p]} for p in prims],
        "materials": [
            {"name": "cutout", "alphaMode": "MASK", "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0}, "metallicFactor": 0}},
            {"name": "hidden", "alphaMode": "MASK", "alphaCutoff": 0.4,
             "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.3],
                                      "metallicFactor": 0}},
            {"name": "blend", "alphaMode": "BLEND",
             "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.3],
                                      "metallicFactor": 0}},
            {"name": "back", "pbrMetallicRoughness": {"metallicFactor": 0}},
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(ALPHA_PNG).decode()}],
        "accessors": blob.accessors,
        "bufferViews": blob.views,
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(data).decode()}],
    }


def glb(doc, binary):
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\x00" * (-len(binary) % 4)
    body = (struct.pack("<I4s", len(text), b"JSON") + text
            + struct.pack("<I4s", len(binary), b"BIN\x00") + binary)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def write(name, data):
    mode = "w" if isinstance(data, str) else "wb"
    with open(os.path.join(HERE, name), mode) as f:
        f.write(data)


def main():
    doc, binary = scene(images_in_views=False, buffer_uri="hierarchy.bin")
    write("hierarchy.gltf", json.dumps(doc, indent=1) + "\n")
    write("hierarchy.bin", binary)
    write("normal.png", NORMAL_PNG)
    doc, binary = scene(images_in_views=True, buffer_uri=None)
    write("hierarchy.glb", glb(doc, binary))
    write("defaults.gltf", json.dumps(defaults_scene(), indent=1) + "\n")
    write("alpha.gltf", json.dumps(alpha_scene(), indent=1) + "\n")


if __name__ == "__main__":
    main()
