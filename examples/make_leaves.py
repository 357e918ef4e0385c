#!/usr/bin/env python3
"""Writes examples/leaves.gltf, the alpha-cutout gallery scene (standard library only).

    python3 examples/make_leaves.py        # from the repository root
    lightpath render examples/leaves.gltf --spp 256 -o docs/gallery/leaves.png

A canopy of 400 leaves, each a quad cut out of a 64x64 RGBA leaf texture (glTF
`alphaMode` `MASK`), over a grey floor, lit by a sun (a distant `KHR_lights_punctual`
point light) and a dim emissive sky quad overhead: the sun's shadow on the floor
is the leaves' outlines, not squares. A red pane of alpha 0.5 (`BLEND`) stands beside the
canopy: half of the light and of the view pass through it (stochastic transparency).
Everything (buffer and image) is embedded as data: URIs; the output is deterministic.
"""

import base64
import json
import math
import os
import random
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def png_rgba(size, pixel):
    """An 8-bit RGBA PNG of size x size; pixel(x, y) -> (r, g, b, a), row 0 at the top."""
    raw = b"".join(b"\x00" + bytes(c for x in range(size) for c in pixel(x, y))
                   for y in range(size))

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9))
            + chunk(b"IEND", b""))


def leaf_pixel(x, y, size=64):
    """A pointed leaf along the image's diagonal, with a darker midrib and a stem."""
    u = (x + 0.5) / size
    v = (y + 0.5) / size
    # Leaf coordinates: s along the blade (0 at the stem), w across it.
    s = (u + v) / 2 ** 0.5 / 2 ** 0.5
    w = (u - v) / 2 ** 0.5
    half_width = 0.22 * math.sin(math.pi * min(max((s - 0.08) / 0.9, 0.0), 1.0)) ** 0.8
    inside = 0.08 < s < 0.98 and abs(w) < half_width
    stem = s <= 0.08 and abs(w) < 0.012
    if not (inside or stem):
        return (0, 0, 0, 0)
    shade = 0.75 + 0.25 * math.cos(9 * s)
    if abs(w) < 0.01 or stem:
        return (int(90 * shade), int(120 * shade), 40, 255)
    return (int(60 * shade), int(150 * shade), int(45 * shade), 255)


class Blob:
    def __init__(self):
        self.data = bytearray()
        self.views = []
        self.accessors = []

    def accessor(self, fmt, kind, values, ctype, target):
        while len(self.data) % 4:
            self.data.append(0)
        offset = len(self.data)
        for v in values:
            self.data += struct.pack("<" + fmt, *v) if isinstance(v, (list, tuple)) \
                else struct.pack("<" + fmt, v)
        self.views.append({"buffer": 0, "byteOffset": offset,
                           "byteLength": len(self.data) - offset, "target": target})
        acc = {"bufferView": len(self.views) - 1, "componentType": ctype,
               "count": len(values), "type": kind}
        if kind == "VEC3" and ctype == 5126:
            acc["min"] = [min(v[i] for v in values) for i in range(3)]
            acc["max"] = [max(v[i] for v in values) for i in range(3)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def main():
    rng = random.Random(7)
    blob = Blob()

    def add(n, x):
        return [n[i] + x[i] for i in range(3)]

    def scale(v, k):
        return [c * k for c in v]

    def quad_prim(corners, uvs, material):
        pos = blob.accessor("3f", "VEC3", corners, 5126, 34962)
        uv = blob.accessor("2f", "VEC2", uvs, 5126, 34962)
        idx = blob.accessor("H", "SCALAR", [0, 1, 2, 0, 2, 3], 5123, 34963)
        return {"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": idx,
                "material": material}

    # The canopy: one mesh of 400 leaf quads (a quad is two triangles, uv over the
    # whole texture), randomly turned, in a flattened ellipsoid above the floor.
    pos, uv, idx = [], [], []
    for k in range(400):
        while True:
            c = [rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)]
            if sum(x * x for x in c) < 1:
                break
        centre = [1.4 * c[0], 2.1 + 0.45 * c[1], 1.4 * c[2]]
        # Two orthogonal edge directions of a random frame, tilted towards horizontal.
        a = [rng.gauss(0, 1), rng.gauss(0, 0.5), rng.gauss(0, 1)]
        b = [rng.gauss(0, 1), rng.gauss(0, 0.5), rng.gauss(0, 1)]
        na = math.sqrt(sum(x * x for x in a))
        a = scale(a, 1 / na)
        d = sum(a[i] * b[i] for i in range(3))
        b = [b[i] - d * a[i] for i in range(3)]
        b = scale(b, 1 / math.sqrt(sum(x * x for x in b)))
        size = rng.uniform(0.22, 0.32)
        ea, eb = scale(a, size / 2), scale(b, size / 2)
        base = len(pos)
        for sa, sb, t in [(-1, -1, (0, 1)), (1, -1, (1, 1)), (1, 1, (1, 0)), (-1, 1, (0, 0))]:
            pos.append(add(centre, add(scale(ea, sa), scale(eb, sb))))
            uv.append(list(t))
        idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    leaves = {"attributes": {
        "POSITION": blob.accessor("3f", "VEC3", pos, 5126, 34962),
        "TEXCOORD_0": blob.accessor("2f", "VEC2", uv, 5126, 34962)},
        "indices": blob.accessor("H", "SCALAR", idx, 5123, 34963), "material": 0}
    floor = quad_prim([[-6, 0, -6], [-6, 0, 6], [6, 0, 6], [6, 0, -6]],
                      [[0, 0], [0, 1], [1, 1], [1, 0]], 1)
    pane = quad_prim([[1.7, 0, -0.3], [2.5, 0, 0.5], [2.5, 1.6, 0.5], [1.7, 1.6, -0.3]],
                     [[0, 1], [1, 1], [1, 0], [0, 0]], 2)
    sky = quad_prim([[-40, 30, -40], [40, 30, -40], [40, 30, 40], [-40, 30, 40]],
                    [[0, 0], [1, 0], [1, 1], [0, 1]], 3)
    trunk = quad_prim([[-0.06, 0, 0], [0.06, 0, 0], [0.06, 1.9, 0], [-0.06, 1.9, 0]],
                      [[0, 1], [1, 1], [1, 0], [0, 0]], 4)
    trunk2 = quad_prim([[0, 0, -0.06], [0, 0, 0.06], [0, 1.9, 0.06], [0, 1.9, -0.06]],
                       [[0, 1], [1, 1], [1, 0], [0, 0]], 4)
    data = bytes(blob.data)
    texture = png_rgba(64, leaf_pixel)

    def look_at(eye, target):
        # glTF cameras look down their -Z: a yaw then a pitch.
        d = [target[i] - eye[i] for i in range(3)]
        yaw = math.atan2(-d[0], -d[2])
        pitch = math.atan2(d[1], math.hypot(d[0], d[2]))
        qy = [0, math.sin(yaw / 2), 0, math.cos(yaw / 2)]
        qx = [math.sin(pitch / 2), 0, 0, math.cos(pitch / 2)]
        # q = qy * qx
        x1, y1, z1, w1 = qy
        x2, y2, z2, w2 = qx
        return [w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
                w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2]

    def sun_position(direction, distance):
        # A distant point light (below the sky quad, which would shadow a directional
        # light) shining along `direction` onto the canopy's centre.
        n = math.sqrt(sum(x * x for x in direction))
        return [[0, 2, 0][i] - distance * direction[i] / n for i in range(3)]

    eye = [3.9, 3.9, 4.5]
    doc = {
        "asset": {"version": "2.0", "generator": "lightpath examples/make_leaves.py"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3, 4, 5, 6, 7]}],
        "nodes": [
            {"name": "canopy", "mesh": 0},
            {"name": "floor", "mesh": 1},
            {"name": "pane", "mesh": 2},
            {"name": "sky", "mesh": 3},
            {"name": "camera", "translation": eye, "rotation": look_at(eye, [0.45, 0.8, 0]),
             "camera": 0},
            {"name": "sun", "translation": sun_position([-0.55, -1.0, -0.35], 20.0),
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "trunk", "mesh": 4},
            {"name": "trunk2", "mesh": 5},
        ],
        "meshes": [{"name": "leaves", "primitives": [leaves]},
                   {"name": "floor", "primitives": [floor]},
                   {"name": "pane", "primitives": [pane]},
                   {"name": "sky", "primitives": [sky]},
                   {"name": "trunk", "primitives": [trunk]},
                   {"name": "trunk2", "primitives": [trunk2]}],
        "materials": [
            {"name": "leaf", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": True,
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                      "metallicFactor": 0, "roughnessFactor": 0.7}},
            {"name": "floor", "pbrMetallicRoughness": {
                "baseColorFactor": [0.6, 0.58, 0.55, 1], "metallicFactor": 0,
                "roughnessFactor": 1}},
            {"name": "pane", "alphaMode": "BLEND", "doubleSided": True,
             "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.08, 0.5],
                                      "metallicFactor": 0, "roughnessFactor": 0.4}},
            {"name": "sky", "emissiveFactor": [0.55, 0.7, 1.0],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 0.6}},
             "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0}},
            {"name": "bark", "doubleSided": True, "pbrMetallicRoughness": {
                "baseColorFactor": [0.25, 0.17, 0.1, 1], "metallicFactor": 0,
                "roughnessFactor": 1}},
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9729}],
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(texture).decode()}],
        "cameras": [{"type": "perspective", "perspective": {
            "yfov": 0.75, "aspectRatio": 1.5, "znear": 0.1, "zfar": 100}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 0.93, 0.8], "intensity": 1200.0}]}},
        "accessors": blob.accessors,
        "bufferViews": blob.views,
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(data).decode()}],
    }
    with open(os.path.join(HERE, "leaves.gltf"), "w") as f:
        f.write(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
