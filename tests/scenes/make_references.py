#!/usr/bin/env python3
"""Analytic reference images for the scenes in this folder.

An independent implementation in float64 numpy (not lightpath's code): cameras, the
canonical shapes, transforms in document order, normals by the inverse transpose, and
the `normals`, `distance` and `camera` outputs, with 16x16 stratified samples per
pixel. Writes <id>_ref.exr next to each scene. Needs numpy and OpenEXR:

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install numpy OpenEXR
    /tmp/venv/bin/python tests/scenes/make_references.py
"""
import math
import os
import xml.etree.ElementTree as ET

import numpy as np
import OpenEXR

HERE = os.path.dirname(os.path.abspath(__file__))
SUB = 16  # stratified samples per pixel and axis


def vec(s):
    v = [float(x) for x in s.replace(",", " ").split()]
    return np.array(v * 3 if len(v) == 1 else v)


def rotation(axis, deg):
    a = axis / np.linalg.norm(axis)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    x, y, z = a
    r = np.array([
        [c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
        [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
        [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)],
    ])
    m = np.eye(4)
    m[:3, :3] = r
    return m


def transform(node):
    m = np.eye(4)
    if node is None:
        return m
    for step in node:
        s = np.eye(4)
        a = step.attrib
        if step.tag == "translate":
            s[:3, 3] = [float(a.get(k, 0)) for k in "xyz"]
        elif step.tag == "scale":
            v = vec(a["value"]) if "value" in a else np.array([float(a.get(k, 1)) for k in "xyz"])
            s = np.diag([*v, 1.0])
        elif step.tag == "rotate":
            s = rotation(vec(a["axis"]), float(a["angle"]))
        elif step.tag == "matrix":
            s = vec(a["value"]).reshape(4, 4)
        elif step.tag == "lookat":
            o, t, up = vec(a["origin"]), vec(a["target"]), vec(a.get("up", "0,1,0"))
            z = (t - o) / np.linalg.norm(t - o)
            x = np.cross(up, z)
            x /= np.linalg.norm(x)
            y = np.cross(z, x)
            s[:3, 0], s[:3, 1], s[:3, 2], s[:3, 3] = x, y, z, o
        m = s @ m
    return m


def props(node):
    p = dict(node.attrib)
    for c in node:
        if "name" in c.attrib and "value" in c.attrib:
            p[c.attrib["name"]] = c.attrib["value"]
    return p


def camera_rays(cam, w, h):
    p = props(cam)
    m = transform(cam.find("transform"))
    j = (np.arange(SUB) + 0.5) / SUB
    px = (np.arange(w)[:, None] + j[None, :]).reshape(-1)
    py = (np.arange(h)[:, None] + j[None, :]).reshape(-1)
    fx, fy = np.meshgrid(2 * px / w - 1, 2 * py / h - 1)  # [h*SUB, w*SUB]
    kind = cam.attrib["type"]
    valid = np.ones_like(fx, dtype=bool)
    if kind == "perspective":
        t = math.tan(math.radians(float(p["fov"])) / 2)
        axis = p.get("fovAxis", "x")
        sx, sy = (t, t * h / w) if axis == "x" else (t * w / h, t)
        d = np.stack([fx * sx, fy * sy, np.ones_like(fx)], -1)
        o = np.zeros_like(d)
    elif kind == "orthographic":
        size = float(p.get("size", 1))
        o = np.stack([fx * size, fy * size * h / w, np.zeros_like(fx)], -1)
        d = np.zeros_like(o)
        d[..., 2] = 1
    elif kind == "fisheye":
        assert p["mapping"] == "equisolid"
        fov = math.radians(float(p["fov"]))
        nx, ny = fx * w / min(w, h), fy * h / min(w, h)
        r = np.hypot(nx, ny)
        valid = r <= 1
        rmax = 2 * math.sin(fov / 4)
        theta = 2 * np.arcsin(np.clip(r * rmax / 2, -1, 1))
        phi = np.arctan2(ny, nx)
        d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)
        o = np.zeros_like(d)
    else:
        raise ValueError(kind)
    o = o @ m[:3, :3].T + m[:3, 3]
    d = d @ m[:3, :3].T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return o, d, valid


def hit_shape(kind, attrib, o, d):
    """Object-space closest hit t > 1e-6 and normal; t = inf on a miss."""
    inf = np.full(o.shape[:-1], np.inf)
    n = np.zeros_like(o)
    cands = []
    with np.errstate(divide="ignore", invalid="ignore"):
        if kind == "sphere":
            a = (d * d).sum(-1)
            b = 2 * (o * d).sum(-1)
            c = (o * o).sum(-1) - 1
            disc = b * b - 4 * a * c
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            for t in [(-b - sq) / (2 * a), (-b + sq) / (2 * a)]:
                p = o + t[..., None] * d
                cands.append((t, p))
        elif kind in ("rectangle", "disk", "plane"):
            t = -o[..., 2] / d[..., 2]
            p = o + t[..., None] * d
            if kind == "rectangle":
                t = np.where((abs(p[..., 0]) <= 1) & (abs(p[..., 1]) <= 1), t, np.nan)
            elif kind == "disk":
                t = np.where(p[..., 0] ** 2 + p[..., 1] ** 2 <= 1, t, np.nan)
            cands.append((t, np.broadcast_to([0, 0, 1.0], p.shape)))
        elif kind == "cube":
            for ax in range(3):
                for side in (-1.0, 1.0):
                    t = (side - o[..., ax]) / d[..., ax]
                    p = o + t[..., None] * d
                    others = [k for k in range(3) if k != ax]
                    ok = (abs(p[..., others[0]]) <= 1) & (abs(p[..., others[1]]) <= 1)
                    nn = np.zeros(3)
                    nn[ax] = side
                    cands.append((np.where(ok, t, np.nan), np.broadcast_to(nn, p.shape)))
        elif kind == "cylinder":
            a = d[..., 0] ** 2 + d[..., 1] ** 2
            b = 2 * (o[..., 0] * d[..., 0] + o[..., 1] * d[..., 1])
            c = o[..., 0] ** 2 + o[..., 1] ** 2 - 1
            disc = b * b - 4 * a * c
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            for t in [(-b - sq) / (2 * a), (-b + sq) / (2 * a)]:
                p = o + t[..., None] * d
                ok = (p[..., 2] >= 0) & (p[..., 2] <= 1)
                nn = p.copy()
                nn[..., 2] = 0
                cands.append((np.where(ok, t, np.nan), nn))
            if attrib.get("caps") == "true":
                for z, nz in ((0.0, -1.0), (1.0, 1.0)):
                    t = (z - o[..., 2]) / d[..., 2]
                    p = o + t[..., None] * d
                    ok = p[..., 0] ** 2 + p[..., 1] ** 2 <= 1
                    cands.append((np.where(ok, t, np.nan), np.broadcast_to([0, 0, nz], p.shape)))
        else:
            raise ValueError(kind)
    best = inf.copy()
    for t, nn in cands:
        t = np.where(np.isfinite(t) & (t > 1e-6), t, np.inf)
        closer = t < best
        best = np.where(closer, t, best)
        n = np.where(closer[..., None], nn, n)
    return best, n


def render(path):
    root = ET.parse(path).getroot()
    integ = root.find("integrator")
    scene = integ.find("scene")
    cam = scene.find("camera")
    cp = props(cam)
    w, h = int(cp["width"]), int(cp["height"])
    o, d, valid = camera_rays(cam, w, h)
    kind = integ.attrib["type"]
    if kind == "camera":
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (1 - o[..., 2]) / d[..., 2]
            q = o + t[..., None] * d
            line = np.zeros(t.shape, dtype=bool)
            for k in (0, 1):
                c = q[..., k]
                line |= np.isfinite(c) & (np.mod(abs(c) * 10, 1) < 0.1)
        img = np.where(line[..., None], 0.0, (d + 1) / 2)
    else:
        best = np.full(o.shape[:-1], np.inf)
        normal = np.zeros_like(o)
        for inst in scene.findall("instance"):
            shape = inst.find("shape")
            m = transform(inst.find("transform"))
            mi = np.linalg.inv(m)
            oo = o @ mi[:3, :3].T + mi[:3, 3]
            dd = d @ mi[:3, :3].T
            t, n = hit_shape(shape.attrib["type"], shape.attrib, oo, dd)
            n = n @ mi[:3, :3]  # inverse transpose
            closer = t < best
            best = np.where(closer, t, best)
            normal = np.where(closer[..., None], n, normal)
        hit = np.isfinite(best)
        if integ.attrib["variable"] == "normals":
            nn = normal / np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-30)
            img = np.where(hit[..., None], (nn + 1) / 2, 0.5)
        else:  # distance
            img = np.repeat(np.where(hit, best, 0.0)[..., None], 3, -1)
    img = np.where(valid[..., None], img, 0.0)
    img = img.reshape(h, SUB, w, SUB, 3).mean(axis=(1, 3)).astype(np.float32)
    out = os.path.join(os.path.dirname(path), root.attrib["id"] + "_ref.exr")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": img}).write(out)
    print("wrote", out)


if __name__ == "__main__":
    for f in sorted(os.listdir(HERE)):
        if f.endswith(".xml"):
            render(os.path.join(HERE, f))
