"""Makes the textures of the Mitsuba comparison scenes and their Mitsuba 3 references.

    python3 tests/mitsuba/make_references.py textures        # needs numpy + pillow
    python3 tests/mitsuba/make_references.py curves          # the curve files
    python3 tests/mitsuba/make_references.py serialized      # meshes.serialized
    python3 tests/mitsuba/make_references.py colors          # the vertex-coloured PLY files
    python3 tests/mitsuba/make_references.py references VENV # needs a venv with mitsuba 3

The references are rendered with Mitsuba 3.9.1 (scalar_rgb) through
../shared/tools/mitsuba-ref/render.py at SPP samples per pixel; the test
(crates/lightpath/tests/mitsuba_reference.rs) renders the same files with lightpath and
compares them by relMSE (eps 0.01, as compare.py defines it) and mean brightness.
"""

import pathlib
import subprocess
import sys

HERE = pathlib.Path(__file__).resolve().parent
SCENES = ["box", "materials", "lights", "plastics", "curves", "bspline", "mask", "serialized", "bump", "principled", "scalars", "flip", "colors"]
SPP = 16384


def textures():
    import numpy as np
    from PIL import Image

    # Diagonal colour stripes, 32x32, sRGB.
    y, x = np.mgrid[0:32, 0:32]
    band = ((x + y) // 4) % 3
    colours = np.array([[220, 60, 40], [240, 220, 200], [40, 90, 200]], dtype=np.uint8)
    Image.fromarray(colours[band]).save(HERE / "stripes.png")
    # Its red channel as a grey image: what reading a float parameter from the first
    # channel instead of the luminance would see (the `scalars` scene's catch test).
    Image.fromarray(colours[band][..., 0]).save(HERE / "stripes_red.png")

    # A tangent-space normal map of round bumps, 32x32, raw (linear) values.
    u = (np.arange(32) + 0.5) / 32
    uu, vv = np.meshgrid(u, u)
    fx, fy = np.cos(uu * 8 * np.pi), np.cos(vv * 8 * np.pi)
    n = np.stack([0.5 * fx, 0.5 * fy, np.ones_like(fx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    Image.fromarray(np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)).save(HERE / "bumps.png")

    # An opacity mask, 16x16, raw grey values 0, 128 and 255: a ring of full opacity
    # with a half-opaque disc inside and a notch cut from its top right.
    y, x = np.mgrid[0:16, 0:16]
    r = np.hypot(x - 7.5, y - 7.5)
    mask = np.where(r < 7.5, 255, 0)
    mask = np.where(r < 4.0, 128, mask)
    mask[(x > 9) & (y < 6)] = 0
    Image.fromarray(mask.astype(np.uint8)).save(HERE / "leaf_mask.png")

    # A height field for `bumpmap`, 16x16, raw grey values: an egg-crate of 3 x 2
    # bumps, brighter to the right so that its level slopes as well.
    y, x = np.mgrid[0:16, 0:16]
    h = 0.45 + 0.35 * np.sin(2 * np.pi * (x + 0.5) / 16 * 3) * np.cos(2 * np.pi * (y + 0.5) / 16 * 2)
    h += 0.15 * x / 15
    Image.fromarray(np.round(h * 255).astype(np.uint8)).save(HERE / "heights.png")


def curves():
    import math

    # (No comment lines: Mitsuba's reader takes every non-empty line as a point.)
    # Helical strands around a vertical axis, tapering from 0.045 to 0.01, 48 points
    # each: a tuft of "hair" standing on the floor.
    lines = []
    for k in range(7):
        phase = 2 * math.pi * k / 7
        cx, cz = 0.35 * math.cos(phase), 0.35 * math.sin(phase) - 0.1
        if lines:
            lines.append("")
        for i in range(48):
            s = i / 47
            a = phase + 5 * math.pi * s
            x = cx + 0.12 * math.cos(a)
            z = cz + 0.12 * math.sin(a)
            y = 0.02 + 1.1 * s
            r = 0.045 + (0.01 - 0.045) * s
            lines.append(f"{x:.6f} {y:.6f} {z:.6f} {r:.6f}")
    (HERE / "curves_helices.txt").write_text("\n".join(lines) + "\n")
    # A zigzag wire of constant radius with sharp joints, in a unit box (the scene
    # scales it by to_world, which moves the points but keeps the radii).
    lines = []
    for i in range(9):
        lines.append(f"{i / 8:.6f} {0.15 + 0.55 * (i % 2):.6f} 0.0 0.02")
    (HERE / "curves_wire.txt").write_text("\n".join(lines) + "\n")
    # B-spline strands (`bsplinecurve`): five wavy strands of 9 control points each,
    # coarse enough that the smooth curve stands well apart from its control polygon,
    # tapering from 0.05 to 0.006; and a thick arch of constant radius whose ends reach
    # below the floor (Mitsuba's cubic curves are open at their ends, ours are capped, so
    # no end is left in view with a radius that would show the difference).
    lines = []
    for k in range(5):
        if lines:
            lines.append("")
        x0 = -0.6 + 0.3 * k
        for i in range(9):
            s = i / 8
            x = x0 + 0.13 * math.sin(3.1 * math.pi * s + k)
            z = -0.2 + 0.15 * math.cos(2.3 * math.pi * s + 2 * k)
            y = -0.3 + 1.4 * s
            r = 0.05 + (0.006 - 0.05) * s
            lines.append(f"{x:.6f} {y:.6f} {z:.6f} {r:.6f}")
    lines.append("")
    for i in range(8):
        a = math.pi * (i - 1) / 5
        lines.append(f"{0.8 * math.cos(a):.6f} {0.75 * math.sin(a) - 0.12:.6f} 0.35 0.06")
    (HERE / "bspline_strands.txt").write_text("\n".join(lines) + "\n")


def serialized():
    import math
    import struct
    import zlib

    def record(flags, positions, normals, uvs, triangles, double=False):
        """One mesh of Mitsuba's serialized format, version 4."""
        fmt = "<d" if double else "<f"
        flags |= 0x2000 if double else 0x1000
        body = struct.pack("<I", flags) + b"mesh\0"
        body += struct.pack("<QQ", len(positions), len(triangles))
        for array in (positions, normals, uvs):
            body += b"".join(struct.pack(fmt, x) for v in array for x in v)
        body += b"".join(struct.pack("<III", *t) for t in triangles)
        return struct.pack("<HH", 0x041C, 4) + zlib.compress(body)

    # Mesh 0: a UV sphere of 12 x 8 quads with no normals (the readers compute smooth
    # ones), its poles pinched, placed by a non-uniform scale in the scene.
    positions, triangles = [], []
    rows, cols = 8, 12
    for i in range(rows + 1):
        theta = math.pi * i / rows
        for j in range(cols):
            phi = 2 * math.pi * j / cols
            positions.append((math.sin(theta) * math.cos(phi), math.cos(theta),
                              math.sin(theta) * math.sin(phi)))
    for i in range(rows):
        for j in range(cols):
            a, b = i * cols + j, i * cols + (j + 1) % cols
            c, d = a + cols, b + cols
            if i > 0:
                triangles.append((a, b, c))
            if i < rows - 1:
                triangles.append((b, d, c))
    sphere = record(0, positions, [], [], triangles)
    # Mesh 1: a quad with normals and texture coordinates, in double precision.
    quad = record(0x3, [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)],
                  [(0, 1, 0)] * 4, [(0, 0), (2, 0), (2, 2), (0, 2)],
                  [(0, 2, 1), (0, 3, 2)], double=True)
    # Mesh 2: a tent, two triangles folded along a ridge, with smooth normals in the
    # file that the scene discards (face_normals).
    tent = record(0x1, [(-1, 0, -1), (1, 0, -1), (0, 1, 0), (-1, 0, 1), (1, 0, 1)],
                  [(0, 1, 0)] * 5, [],
                  [(0, 2, 1), (3, 4, 2)])
    data, offsets = b"", []
    for r in (sphere, quad, tent):
        offsets.append(len(data))
        data += r
    data += b"".join(struct.pack("<Q", o) for o in offsets) + struct.pack("<I", 3)
    (HERE / "meshes.serialized").write_bytes(data)


def colors():
    """PLY meshes with float vertex colours (`r`, `g`, `b`: Mitsuba's `vertex_color`) and
    face colours (`face_color`)."""
    import math

    def ply(name, positions, colours, faces):
        lines = ["ply", "format ascii 1.0", f"element vertex {len(positions)}"]
        lines += [f"property float {c}" for c in ("x", "y", "z", "r", "g", "b")]
        lines += [f"element face {len(faces)}", "property list uchar int vertex_indices",
                  "end_header"]
        for p, c in zip(positions, colours):
            lines.append(" ".join(f"{x:.6f}" for x in (*p, *c)))
        for f in faces:
            lines.append(" ".join(str(x) for x in (len(f), *f)))
        (HERE / name).write_text("\n".join(lines) + "\n")

    # (Triangles only: Mitsuba 3.9's ascii reader does not take quads.)
    # A UV sphere of 24 x 12 quads (flat triangles, no normals in the file) whose colour
    # runs round the hue circle with longitude and fades to white at the top.
    positions, colours, faces = [], [], []
    rows, cols = 12, 24
    for i in range(rows + 1):
        theta = math.pi * i / rows
        for j in range(cols + 1):
            phi = 2 * math.pi * j / cols
            positions.append((math.sin(theta) * math.cos(phi), math.cos(theta),
                              math.sin(theta) * math.sin(phi)))
            hue = [0.5 + 0.45 * math.cos(phi - k * 2 * math.pi / 3) for k in range(3)]
            w = (1 + math.cos(theta)) / 2
            colours.append(tuple(h * (1 - w) + 0.9 * w for h in hue))
    for i in range(rows):
        for j in range(cols):
            a, b = i * (cols + 1) + j, i * (cols + 1) + j + 1
            faces += [(a, b, b + cols + 1), (a, b + cols + 1, a + cols + 1)]
    ply("colors_sphere.ply", positions, colours, faces)
    # A floor of 4 x 4 quads, its corners' colours red, green, blue and grey.
    positions, colours, faces = [], [], []
    corner = [(0.8, 0.15, 0.1), (0.1, 0.7, 0.2), (0.15, 0.2, 0.8), (0.6, 0.6, 0.6)]
    for i in range(5):
        for j in range(5):
            s, t = i / 4, j / 4
            positions.append((2 * s - 1, 0.0, 2 * t - 1))
            colours.append(tuple(corner[0][k] * (1 - s) * (1 - t) + corner[1][k] * s * (1 - t)
                                 + corner[2][k] * (1 - s) * t + corner[3][k] * s * t
                                 for k in range(3)))
    for i in range(4):
        for j in range(4):
            a = i * 5 + j
            faces += [(a, a + 1, a + 6), (a, a + 6, a + 5)]
    ply("colors_floor.ply", positions, colours, faces)
    # An icosahedron whose 20 faces each have a colour of their own (face `r`, `g`, `b`:
    # Mitsuba's `face_color`).
    g = (1 + math.sqrt(5)) / 2
    positions = [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g),
                 (0, -1, -g), (0, 1, -g), (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
             (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
             (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    lines = ["ply", "format ascii 1.0", f"element vertex {len(positions)}"]
    lines += [f"property float {c}" for c in ("x", "y", "z")]
    lines += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    lines += [f"property float {c}" for c in ("r", "g", "b")]
    lines.append("end_header")
    for p in positions:
        lines.append(" ".join(f"{x / math.hypot(1, g):.6f}" for x in p))
    for k, f in enumerate(faces):
        hue = [0.5 + 0.45 * math.cos(2 * math.pi * (k / 20 - c / 3)) for c in range(3)]
        lines.append(" ".join(str(x) for x in (3, *f)) + " " + " ".join(f"{h:.6f}" for h in hue))
    (HERE / "colors_faces.ply").write_text("\n".join(lines) + "\n")


def references(venv):
    render = HERE.parents[1] / ".." / "shared" / "tools" / "mitsuba-ref" / "render.py"
    for scene in SCENES:
        subprocess.run(
            [f"{venv}/bin/python", str(render), str(HERE / f"{scene}.xml"),
             "--spp", str(SPP), "-o", str(HERE / f"{scene}_mitsuba.exr")],
            check=True,
        )
    # One scene, two filters: filters_mitchell_mitsuba.exr, filters_lanczos_mitsuba.exr.
    for rfilter in ["mitchell", "lanczos"]:
        subprocess.run(
            [f"{venv}/bin/python", str(render), str(HERE / "filters.xml"),
             "--spp", str(SPP), "-D", f"filter={rfilter}",
             "-o", str(HERE / f"filters_{rfilter}_mitsuba.exr")],
            check=True,
        )


if __name__ == "__main__":
    if sys.argv[1] == "textures":
        textures()
    elif sys.argv[1] == "curves":
        curves()
    elif sys.argv[1] == "serialized":
        serialized()
    elif sys.argv[1] == "colors":
        colors()
    else:
        references(sys.argv[2])
