"""Writes furball.txt for examples/curves.xml: 600 curly strands of 10 control points on
a unit sphere, tapering from 0.012 to 0.002 (the file format of Mitsuba 3's linearcurve:
`x y z radius` per line, an empty line between curves). Deterministic: a fixed seed.

    python3 examples/make_furball.py
"""
import math
import pathlib
import random

random.seed(5)
lines = []
for k in range(600):
    # A uniform direction (Fibonacci sphere) with a random tilt and curl.
    z = 1 - 2 * (k + 0.5) / 600
    phi = k * math.pi * (3 - math.sqrt(5))
    r = math.sqrt(1 - z * z)
    n = (r * math.cos(phi), r * math.sin(phi), z)
    # Two tangents.
    a = (0.0, 0.0, 1.0) if abs(n[2]) < 0.9 else (1.0, 0.0, 0.0)
    t1 = (n[1] * a[2] - n[2] * a[1], n[2] * a[0] - n[0] * a[2], n[0] * a[1] - n[1] * a[0])
    l1 = math.sqrt(sum(c * c for c in t1))
    t1 = tuple(c / l1 for c in t1)
    t2 = (n[1] * t1[2] - n[2] * t1[1], n[2] * t1[0] - n[0] * t1[2], n[0] * t1[1] - n[1] * t1[0])
    length = 0.45 + 0.2 * random.random()
    curl = random.uniform(-2.5, 2.5)
    tilt = random.uniform(0, 2 * math.pi)
    if lines:
        lines.append("")
    for i in range(10):
        s = i / 9
        bend = 0.25 * s * s
        ang = tilt + curl * s
        p = [0.97 * n[c] + length * s * n[c]
             + bend * (math.cos(ang) * t1[c] + math.sin(ang) * t2[c]) for c in range(3)]
        radius = 0.012 + (0.002 - 0.012) * s
        lines.append(f"{p[0]:.5f} {p[1]:.5f} {p[2]:.5f} {radius:.5f}")
pathlib.Path(__file__).with_name("furball.txt").write_text("\n".join(lines) + "\n")
