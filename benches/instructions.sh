#!/usr/bin/env bash
# Instructions executed (callgrind's Ir) by a small fixed render: the Cornell box at
# 64x64, 4 spp, depth 8, one thread. A render is a pure function of its inputs, so the
# count repeats to within about 0.01% (the thread pool's start-up varies) where timings
# on a shared machine vary by 10-15%: use it to compare two builds of a change that is
# too small to time. (valgrind hides AVX-512
# from the program, so the AVX2 paths are the ones counted. valgrind 3.19, Debian 12's,
# stops at some AVX2 instructions; the script then counts the baseline code instead,
# `--simd baseline`, and says so. SIMD=baseline picks that tier from the start.)
#
#   benches/instructions.sh [BIN] [SAMPLER] [extra render options...]
#   benches/instructions.sh target/release/lightpath sobol --accel bvh8-hq
#
# Needs valgrind, and the Cornell box meshes from ../shared (as benches/scenes/cbox.xml).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-target/release/lightpath}
SAMPLER=${2:-independent}
shift $(( $# < 2 ? $# : 2 ))
command -v valgrind >/dev/null || { echo "valgrind is not installed" >&2; exit 1; }
[ -x "$BIN" ] || cargo build --release --bin lightpath -q
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
count() { # extra options... -> the log in $OUT/log
    valgrind --tool=callgrind --callgrind-out-file="$OUT/callgrind.out" "$BIN" render \
        benches/scenes/cbox.xml -D spp=4 -D depth=8 -D res=64 -D sampler="$SAMPLER" \
        --threads 1 -o "$OUT/image.exr" -q "$@" 2>"$OUT/log"
}
SIMD=${SIMD:-}
if [ -n "$SIMD" ]; then
    count --simd "$SIMD" "$@" || { cat "$OUT/log" >&2; exit 1; }
elif ! count "$@"; then
    grep -q "Unrecognised instruction" "$OUT/log" || { cat "$OUT/log" >&2; exit 1; }
    echo "this valgrind does not decode the AVX2 code: counting --simd baseline" >&2
    count --simd baseline "$@" || { cat "$OUT/log" >&2; exit 1; }
fi
sed -n 's/.*Collected : \([0-9]*\).*/\1/p' "$OUT/log"
