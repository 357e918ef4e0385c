#!/usr/bin/env python3
"""Tracing speed against Embree on a path tracer's own rays, in the same run.

    benches/path-rays.py [SCENE] [--spp 16] [--rounds 5] [--reps 5] [--accel bvh8]
                         [--lightpath PATH] [--robust] [--out DIR] [-D KEY=VALUE ...]

`lightpath render SCENE --record-rays DIR` (one thread, so that the files hold the
batches in the order one thread traced them) writes the closest-hit rays of the paths
(camera rays and bounces, `paths`) and the shadow rays (`shadow`) with the scene's
triangles; then `lightpath bench` and `embree-rays` (benches/embree-rays.cpp, built here
against the system's Embree 3: `apt-get install libembree-dev g++`) take turns for
--rounds rounds timing both sets ray by ray and in packets of sixteen consecutive rays
(`rtcIntersect16`/`rtcOccluded16` for Embree). The table gives each tool's median
Mrays/s, one thread / all threads, and the median of the rounds' ratios (lightpath over
Embree; above 1 is faster).

SCENE defaults to Mitsuba's Cornell box in ../shared (256x256, depth 8, as
benches/mitsuba-compare.sh renders it). Only Python's standard library is used.
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys

SETS = ("paths", "shadow")
MODES = ("single", "packet")


def figures(traversal):
    """(variant, mode, set) -> median Mrays/s, from either tool's `traversal` JSON."""
    out = {}
    for v in ("st", "mt"):
        for s in SETS:
            out[(v, "single", s)] = traversal[v][s]["mrays_per_s_median"]
            out[(v, "packet", s)] = traversal[v]["packet"][s]["mrays_per_s_median"]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?",
                    default="../shared/models/cornell-box/mitsuba/cbox-rgb.xml")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--accel", default="bvh8")
    ap.add_argument("--robust", action="store_true", help="Embree's watertight mode")
    ap.add_argument("--lightpath", default="target/release/lightpath")
    ap.add_argument("--out", default="target/path-rays")
    ap.add_argument("-D", dest="defines", action="append",
                    help="scene parameter (default for the Cornell box: max_depth=8, res=256)")
    a = ap.parse_args()
    defines = a.defines if a.defines is not None else (
        ["max_depth=8", "res=256"] if a.scene.endswith("cbox-rgb.xml") else [])
    if not os.path.exists(a.lightpath):
        sys.exit(f"path-rays: {a.lightpath} not found (cargo build --release)")
    if not os.path.exists(a.scene):
        sys.exit(f"path-rays: {a.scene} not found")
    os.makedirs(a.out, exist_ok=True)
    embree = os.path.join(a.out, "embree-rays")
    source = os.path.join(os.path.dirname(os.path.abspath(__file__)), "embree-rays.cpp")
    if not os.path.exists(embree) or os.path.getmtime(embree) < os.path.getmtime(source):
        if shutil.which("g++") is None or not os.path.exists("/usr/include/embree3/rtcore.h"):
            sys.exit("path-rays: needs g++ and Embree 3 (apt-get install libembree-dev g++)")
        subprocess.run(["g++", "-O2", "-march=native", "-std=c++17", "-o", embree, source,
                        "-lembree3", "-lpthread"], check=True)
    rays = os.path.join(a.out, "rays")
    cmd = [a.lightpath, "render", a.scene, "-D", f"spp={a.spp}", "--threads", "1",
           "--record-rays", rays, "-o", os.path.join(a.out, "image.exr"), "-q"]
    for d in defines:
        cmd += ["-D", d]
    subprocess.run(cmd, check=True)
    mesh = os.path.join(rays, "scene.obj")
    rounds = []
    for r in range(a.rounds):
        out = subprocess.run([embree, rays, "--reps", str(a.reps)] +
                             (["--robust"] if a.robust else []),
                             check=True, capture_output=True, text=True).stdout
        e = figures(json.loads(out)["traversal"])
        lj = os.path.join(a.out, "lightpath.json")
        subprocess.run([a.lightpath, "bench", mesh, "--rays", rays, "--packet", "--accel",
                        a.accel, "--reps", str(a.reps), "--json", lj],
                       check=True, stdout=subprocess.DEVNULL)
        with open(lj) as f:
            l = figures(json.load(f)["accels"][a.accel]["traversal"])
        rounds.append((e, l))
        line = " ".join(f"{s} {m} {l[('st', m, s)] / e[('st', m, s)]:.3f}/"
                        f"{l[('mt', m, s)] / e[('mt', m, s)]:.3f}"
                        for s in SETS for m in MODES)
        print(f"round {r + 1}: {line}", file=sys.stderr, flush=True)
    med = statistics.median
    print(f"{a.scene}, {a.spp} spp: {len(rounds)} alternated rounds, medians; Mrays/s "
          f"one thread / all threads; ratio lightpath {a.accel} / Embree")
    print(f"{'set':7} {'mode':7} {'Embree':>15} {'lightpath':>15} {'ratio':>13}")
    for s in SETS:
        for m in MODES:
            cols = [f"{med(x[who][(v, m, s)] for x in rounds):.2f}" for who in (0, 1)
                    for v in ("st", "mt")]
            ratio = " / ".join(f"{med(l[(v, m, s)] / e[(v, m, s)] for e, l in rounds):.3f}"
                               for v in ("st", "mt"))
            print(f"{s:7} {m:7} {cols[0] + ' / ' + cols[1]:>15} "
                  f"{cols[2] + ' / ' + cols[3]:>15} {ratio:>13}")


if __name__ == "__main__":
    main()
