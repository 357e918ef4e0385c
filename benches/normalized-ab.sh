#!/usr/bin/env bash
# A/B of two lightpath builds on a render, each run's time normalised by the time the
# same run spent in the ray tracing code. On a shared machine a render's speed drifts by
# 10-20% within minutes, so timings of A and B differ by that much even when run side by
# side; but the drift slows all of a run's code alike. So each run is sampled with
# `perf record -e cpu-clock`, and its figure is (all its samples) / (its samples in the
# tracing functions: the packets' traversal and leaf tests, not the code that hands rays
# and hits in and out of them): time per unit of tracing work. For a change that leaves
# the tracing code alone (the path tracer's glue, the lanes, sampling, shading), B/A of
# that figure is B's time relative to A's. An A/A run gave ratios with a standard
# deviation of 1-2% per pair (timings: about 10%). For a change to the tracing code
# itself it is the other way round: the rest of the render is the same work in both,
# so (A's figure - 1) / (B's figure - 1) is B's tracing time relative to A's, printed
# as "tracing B/A" (session 57: a quad's halves tested together, 0.977).
#
#   benches/normalized-ab.sh ROUNDS A B [SCENE]
#   SPP=32 benches/normalized-ab.sh 6 /tmp/lightpath-before target/release/lightpath
#
# Each round renders A then B on each of the two cores at once (one thread each).
# Prints the medians of both figures and the median, mean and standard deviation of B/A
# over all pairs. Needs perf; the scene defaults to Mitsuba's Cornell box in ../shared.
set -euo pipefail
[ $# -ge 3 ] || { echo "usage: $0 ROUNDS A B [SCENE]" >&2; exit 2; }
ROUNDS=$1; A=$2; B=$3
SCENE=${4:-$(dirname "$0")/../../shared/models/cornell-box/mitsuba/cbox-rgb.xml}
command -v perf >/dev/null || { echo "perf is not installed" >&2; exit 1; }
[ -f "$SCENE" ] || { echo "no scene at $SCENE" >&2; exit 1; }
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
# Samples in all code over samples in the tracing code, for one run of BIN on CPU.
one() { # BIN CPU
    perf record -q -F 20000 -e cpu-clock -o "$OUT/$2.data" taskset -c "$2" "$1" render \
        "$SCENE" -D spp="${SPP:-32}" -D max_depth=8 -D res=256 --threads 1 \
        -o "$OUT/$2.exr" -q >/dev/null 2>&1
    perf report -i "$OUT/$2.data" --no-children --sort symbol -n 2>/dev/null |
        awk '!/^#/ && NF > 2 { n = $2; all += n
             if ($0 ~ /packet_avx512|with_t_max|packet_walk|subtree_ray_by_ray|Bvh8/) traced += n }
             END { if (traced > 0) printf "%.4f\n", all / traced }'
}
lane() { # CPU
    for _ in $(seq "$ROUNDS"); do
        a=$(one "$A" "$1"); b=$(one "$B" "$1")
        echo "$a $b"
    done > "$OUT/pairs-$1"
}
lane 0 & lane 1 & wait
cat "$OUT/pairs-0" "$OUT/pairs-1" | python3 -c "
import sys, statistics as st
rows = [list(map(float, l.split())) for l in sys.stdin if len(l.split()) == 2]
r = [b / a for a, b in rows]
t = [(a - 1) / (b - 1) for a, b in rows]
print('pairs %d  A %.4f  B %.4f (medians of all/tracing samples)  B/A median %.4f  mean %.4f  sd %.4f'
      % (len(r), st.median(x[0] for x in rows), st.median(x[1] for x in rows),
         st.median(r), st.mean(r), st.stdev(r) if len(r) > 1 else 0.0))
print('tracing B/A (for changes to the tracing code) median %.4f  sd %.4f'
      % (st.median(t), st.stdev(t) if len(t) > 1 else 0.0))"
