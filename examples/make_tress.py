"""Writes tress.txt for examples/bspline-hair.xml: 900 wavy strands of 12 control points
hanging from a rod, as cubic B-splines (the file format of Mitsuba 3's
bsplinecurve: `x y z radius` per line, an empty line between curves). Strands gather in
30 locks that share a wave, with a little scatter of their own; each tapers from 0.008 to
0.003. Deterministic: a fixed seed.

    python3 examples/make_tress.py
"""
import math
import pathlib
import random

random.seed(11)
lines = []
LOCKS, PER_LOCK, POINTS = 30, 30, 12
for lock in range(LOCKS):
    # Where the lock leaves the rod (along x, at y = 3.3).
    root = (-1.3 + 2.6 * (lock + 0.5) / LOCKS, 3.3, random.uniform(-0.08, 0.08))
    phase = random.uniform(0, 2 * math.pi)
    wave = random.uniform(0.1, 0.18)
    length = random.uniform(2.0, 2.5)
    sway = random.uniform(-0.3, 0.3)
    for k in range(PER_LOCK):
        off = (random.gauss(0, 0.025), 0.0, random.gauss(0, 0.04))
        jitter = random.uniform(-0.35, 0.35)
        if lines:
            lines.append("")
        for i in range(POINTS):
            s = (i - 1) / (POINTS - 3)  # 0 at the second point, 1 at the last but one
            # Down, waving sideways more as the strand falls, the lock fanning out.
            w = wave * math.sin(6.5 * s + phase + jitter) * min(1.0, 2.5 * max(s, 0.0))
            x = root[0] + w + sway * s * s + off[0] * (1 + 3 * max(s, 0.0))
            y = root[1] - length * s
            z = root[2] + 0.4 * w + off[2] * (1 + 3 * max(s, 0.0))
            r = 0.008 + (0.003 - 0.008) * min(max(s, 0.0), 1.0)
            lines.append(f"{x:.5f} {y:.5f} {z:.5f} {r:.5f}")
pathlib.Path(__file__).with_name("tress.txt").write_text("\n".join(lines) + "\n")
