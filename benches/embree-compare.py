#!/usr/bin/env python3
"""Speed of `lightpath bench` against Embree (`embree-bench bench`) on the same rays.

    benches/embree-compare.py MESH RAYS_DIR [--rounds N] [--accel bvh8]
                              [--embree PATH] [--lightpath PATH] [--robust] [--reps 5]

RAYS_DIR holds the four ray sets that `embree-bench gen-rays MESH --outdir RAYS_DIR`
writes (primary, random, shadow, diffuse); embree-bench's `bench` generates the same
rays itself from the same seed, so both tools trace identical rays. The machine is
noisy (single rounds of the same pair vary by 10-15%), so the tools alternate for
--rounds rounds and the table gives the median Mrays/s of each and the median of the
rounds' ratios, single-threaded / all threads, then the fastest pass of each tool over
all rounds and their ratio (noise from other work on the machine only slows a pass down,
so the fastest pass is the least disturbed figure), plus build time and bytes per
triangle.
Only Python's standard library is used.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

SETS = ("primary", "random", "shadow", "diffuse")


def speeds(traversal):
    """Each set's median and fastest Mrays/s, one and all threads, from either tool's
    JSON (both write the same `traversal` keys)."""
    figures = {}
    for v in ("st", "mt"):
        for s in SETS:
            figures[(v, s)] = traversal[v][s]["mrays_per_s_median"]
            figures[("best", v, s)] = traversal[v][s]["mrays_per_s_best"]
    return figures


def run_embree(exe, mesh, reps, robust, out):
    cmd = [exe, "bench", mesh, "--reps", str(reps), "--build-reps", str(reps), "--out", out]
    if robust:
        cmd.append("--robust")
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(out) as f:
        d = json.load(f)
    return {
        "build_ms": d["build"]["mt"]["ms_median"],
        "bytes_per_tri": d["build"]["mt"]["bytes_per_tri"],
        **speeds(d["traversal"]),
    }


def run_lightpath(exe, mesh, rays, accel, reps, out):
    cmd = [exe, "bench", mesh, "--rays", rays, "--accel", accel, "--reps", str(reps),
           "--json", out]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(out) as f:
        d = json.load(f)["accels"][accel]
    return {
        "build_ms": d["build"]["ms_median"],
        "bytes_per_tri": d["build"]["bytes_per_tri"],
        **speeds(d["traversal"]),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mesh")
    ap.add_argument("rays")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--accel", default="bvh8")
    ap.add_argument("--robust", action="store_true", help="Embree's watertight mode")
    ap.add_argument("--embree", default="/tmp/embree-bench/embree-bench")
    ap.add_argument("--lightpath", action="append",
                    help="lightpath binary (repeat to compare builds; default "
                         "target/release/lightpath)")
    ap.add_argument("--json", help="also write every round's figures here")
    a = ap.parse_args()
    a.lightpath = a.lightpath or ["target/release/lightpath"]
    for exe in (a.embree, *a.lightpath):
        if not os.path.exists(exe):
            sys.exit(f"embree-compare: {exe} not found (build it first)")
    tmp = tempfile.mkdtemp(prefix="embree-compare-")
    rounds = []
    for r in range(a.rounds):
        e = run_embree(a.embree, a.mesh, a.reps, a.robust, os.path.join(tmp, "e.json"))
        ls = [run_lightpath(exe, a.mesh, a.rays, a.accel, a.reps, os.path.join(tmp, "l.json"))
              for exe in a.lightpath]
        rounds.append((e, ls))
        for exe, l in zip(a.lightpath, ls):
            line = " ".join(f"{s[:3]} {l[('st', s)] / e[('st', s)]:.3f}/"
                            f"{l[('mt', s)] / e[('mt', s)]:.3f}" for s in SETS)
            print(f"round {r + 1} {exe}: {line}", file=sys.stderr, flush=True)
    for i, exe in enumerate(a.lightpath):
        report(a, exe, [(e, ls[i]) for e, ls in rounds])
    if a.json:
        with open(a.json, "w") as f:
            json.dump([{"embree": flat(e), "lightpath": [flat(l) for l in ls]}
                       for e, ls in rounds], f, indent=1)


def flat(d):
    return {".".join(k) if isinstance(k, tuple) else k: v for k, v in d.items()}


def report(a, exe, rounds):
    med = statistics.median
    print(f"{exe}: {os.path.basename(a.mesh)}, {len(rounds)} alternated rounds, medians; "
          f"Mrays/s single-threaded / all threads")
    print(f"{'set':8} {'Embree':>15} {'lightpath ' + a.accel:>17} {'ratio':>13}")
    for s in SETS:
        cols = []
        for who in (0, 1):
            cols.append(f"{med(x[who][('st', s)] for x in rounds):.2f} / "
                        f"{med(x[who][('mt', s)] for x in rounds):.2f}")
        ratio = (f"{med(l[('st', s)] / e[('st', s)] for e, l in rounds):.3f} / "
                 f"{med(l[('mt', s)] / e[('mt', s)] for e, l in rounds):.3f}")
        print(f"{s:8} {cols[0]:>15} {cols[1]:>17} {ratio:>13}")
    # Interference from the machine only ever slows a pass down, so the fastest pass of
    # all rounds is the least disturbed estimate of each tool's speed.
    print(f"fastest pass of all rounds ({a.reps} per round), Mrays/s single-threaded / all threads")
    for s in SETS:
        best = [[max(x[who][("best", v, s)] for x in rounds) for v in ("st", "mt")]
                for who in (0, 1)]
        cols = [f"{b[0]:.2f} / {b[1]:.2f}" for b in best]
        ratio = f"{best[1][0] / best[0][0]:.3f} / {best[1][1] / best[0][1]:.3f}"
        print(f"{s:8} {cols[0]:>15} {cols[1]:>17} {ratio:>13}")
    print(f"build ms (all threads): Embree {med(e['build_ms'] for e, _ in rounds):.1f}, "
          f"lightpath {med(l['build_ms'] for _, l in rounds):.1f}, ratio "
          f"{med(e['build_ms'] / l['build_ms'] for e, l in rounds):.3f} (Embree's time / ours)")
    print(f"bytes/tri: Embree {rounds[0][0]['bytes_per_tri']:.1f}, "
          f"lightpath {rounds[0][1]['bytes_per_tri']:.1f}")


if __name__ == "__main__":
    main()
