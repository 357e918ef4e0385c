#!/usr/bin/env bash
# Traversal speed of two lightpath builds, run at the same time, one on each of two CPUs.
# This machine's speed drifts by 10-20% within minutes, so runs one after the other
# compare poorly. Run side by side, both builds see the same drift. The CPUs swap every
# round, so neither build keeps the better core.
#
#   benches/paired-ab.sh ROUNDS MESH RAYS_DIR BIN_A BIN_B [ACCEL]
#   benches/paired-ab.sh 6 ../shared/models/stanford-bunny/bunny.ply /tmp/rays \
#       /tmp/lp_before target/release/lightpath
#
# RAYS_DIR holds any of embree-bench's ray sets (primary.rays, random.rays, shadow.rays,
# diffuse.rays). Each round runs `lightpath bench` with one thread for both builds, in
# parallel. For each set it prints the median, over the rounds, of B's Mrays/s divided by
# A's, with the smallest and largest. A build against itself gave medians within 1% of
# 1.000 over six rounds, and single rounds within 4%: take six rounds or more.
# Needs `taskset` (util-linux) and two CPUs; only Python's standard library is used.
set -euo pipefail
ROUNDS=$1
MESH=$2
RAYS=$3
A=$4
B=$5
ACCEL=${6:-bvh8}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
for r in $(seq "$ROUNDS"); do
    if [ $((r % 2)) = 0 ]; then ca=0; cb=1; else ca=1; cb=0; fi
    RAYON_NUM_THREADS=1 taskset -c $ca "$A" bench "$MESH" --rays "$RAYS" --accel "$ACCEL" \
        --reps 5 --json "$TMP/a.json" >/dev/null 2>&1 &
    pa=$!
    RAYON_NUM_THREADS=1 taskset -c $cb "$B" bench "$MESH" --rays "$RAYS" --accel "$ACCEL" \
        --reps 5 --json "$TMP/b.json" >/dev/null 2>&1 &
    pb=$!
    wait $pa
    wait $pb
    python3 - "$TMP/a.json" "$TMP/b.json" "$ACCEL" >>"$TMP/ratios" <<'EOF'
import json, sys
a, b = (json.load(open(p))["accels"][sys.argv[3]]["traversal"]["st"] for p in sys.argv[1:3])
print(" ".join(f"{k}={b[k]['mrays_per_s_median'] / a[k]['mrays_per_s_median']:.4f}"
               for k in sorted(a) if isinstance(a[k], dict)))
EOF
done
python3 - "$TMP/ratios" <<'EOF'
import collections, statistics, sys
sets = collections.defaultdict(list)
for line in open(sys.argv[1]):
    for kv in line.split():
        k, v = kv.split("=")
        sets[k].append(float(v))
print(f"B/A Mrays/s, one thread each, {len(next(iter(sets.values())))} paired rounds:")
for k, v in sets.items():
    print(f"  {k:8} median {statistics.median(v):.3f}  [{min(v):.3f} .. {max(v):.3f}]")
EOF
