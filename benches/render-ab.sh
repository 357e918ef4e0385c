#!/usr/bin/env bash
# Render speed of several lightpath builds on one scene, alternated round by round (this
# machine's speed drifts by 10-20% within minutes, so only same-sitting medians compare).
#
#   benches/render-ab.sh ROUNDS SCENE BIN... [-- RENDER OPTIONS]
#   benches/render-ab.sh 5 ../shared/models/cornell-box/mitsuba/cbox-rgb.xml \
#       /tmp/lp_before target/release/lightpath -- -D spp=64 -D max_depth=8 -D res=256
#
# Each round renders with every binary on 2 threads (as Mitsuba is measured) and
# reads the render time from --stats-json; prints each binary's median seconds and
# M samples/s, and the median of the per-round ratios to the first binary.
set -euo pipefail
ROUNDS=$1
SCENE=$2
shift 2
BINS=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do BINS+=("$1"); shift; done
[ $# -gt 0 ] && shift
OPTS=("$@")
[ ${#OPTS[@]} -gt 0 ] || OPTS=(-D spp=64 -D max_depth=8 -D res=256)
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
for r in $(seq "$ROUNDS"); do
    for i in "${!BINS[@]}"; do
        "${BINS[$i]}" render "$SCENE" "${OPTS[@]}" --threads 2 -q -o "$TMP/out.exr" \
            --stats-json "$TMP/s.json"
        python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print(d['seconds']['render'], d['samples'] if 'samples' in d else d['width']*d['height']*d['spp'])" \
            "$TMP/s.json" >>"$TMP/times.$i"
    done
done
python3 - "$TMP" "${BINS[@]}" <<'EOF'
import statistics, sys
tmp, bins = sys.argv[1], sys.argv[2:]
rows = [[tuple(map(float, l.split())) for l in open(f"{tmp}/times.{i}")] for i in range(len(bins))]
base = [s for s, _ in rows[0]]
for b, r in zip(bins, rows):
    secs = [s for s, _ in r]
    ratio = statistics.median(b0 / s for b0, s in zip(base, secs))
    print(f"{b:40} {statistics.median(secs):7.3f} s  {r[0][1] / statistics.median(secs) / 1e6:6.3f} M samples/s"
          f"  speed vs first {ratio:.3f}  (rounds: {' '.join(f'{s:.3f}' for s in secs)})")
EOF
