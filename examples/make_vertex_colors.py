"""Writes examples/painted-knot.ply: a (2, 3) torus knot as a tube of 200 x 16 quads
(split into triangles) with smooth normals, its vertices painted with a rainbow along
the knot and a soft dark stripe that winds around the tube; binary little-endian,
8-bit sRGB colours.

    python3 examples/make_vertex_colors.py
"""

import colorsys
import math
import pathlib
import struct

HERE = pathlib.Path(__file__).resolve().parent
ALONG, AROUND = 200, 16


def knot(t):
    """The (2, 3) torus knot, radius about 1.5."""
    r = 1.0 + 0.45 * math.cos(3 * t)
    return (r * math.cos(2 * t), 0.45 * math.sin(3 * t), r * math.sin(2 * t))


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit(a):
    n = math.sqrt(sum(x * x for x in a))
    return tuple(x / n for x in a)


def main():
    vertices, faces = [], []
    for i in range(ALONG):
        t = 2 * math.pi * i / ALONG
        c = knot(t)
        tangent = unit(sub(knot(t + 1e-3), knot(t - 1e-3)))
        normal = unit(cross(tangent, (0.0, 1.0, 0.0)))
        binormal = cross(tangent, normal)
        for j in range(AROUND):
            a = 2 * math.pi * j / AROUND
            d = tuple(math.cos(a) * n + math.sin(a) * b for n, b in zip(normal, binormal))
            p = tuple(x + 0.22 * y for x, y in zip(c, d))
            rgb = colorsys.hsv_to_rgb(i / ALONG, 0.75, 0.95)
            # A soft dark stripe winding three times around the tube along the knot.
            k = (0.5 + 0.5 * math.cos(a - 3 * t)) ** 2
            rgb = tuple((1 - 0.85 * k) * x for x in rgb)
            vertices.append((p, d, tuple(round(255 * x) for x in rgb)))
    for i in range(ALONG):
        for j in range(AROUND):
            a = i * AROUND + j
            b = i * AROUND + (j + 1) % AROUND
            c = ((i + 1) % ALONG) * AROUND + (j + 1) % AROUND
            d = ((i + 1) % ALONG) * AROUND + j
            faces += [(a, b, c), (a, c, d)]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = b"".join(struct.pack("<ffffffBBB", *p, *n, *rgb) for p, n, rgb in vertices)
    body += b"".join(struct.pack("<Biii", 3, *f) for f in faces)
    (HERE / "painted-knot.ply").write_bytes(header.encode() + body)


if __name__ == "__main__":
    main()
