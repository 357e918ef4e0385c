#!/usr/bin/env bash
# Speed and equal-time error of lightpath against Mitsuba 3 on the Cornell box, measured
# in one run on this machine (see ../shared/tools/mitsuba-ref/README.md for the setup:
# a venv with mitsuba, and Debian's libllvm19 for the llvm variants).
#
#   benches/mitsuba-compare.sh [VENV]      (default VENV: /tmp/venv-mitsuba)
#   ROUNDS=5 benches/mitsuba-compare.sh    (alternating timed rounds, default 3)
#
# Prints samples/s of lightpath (independent and sobol samplers) and of Mitsuba's
# llvm_ad_rgb and scalar_rgb variants at 256x256, max depth 8, 2 threads, and the relMSE
# of each against a high-sample Mitsuba reference when both render for the same time.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${1:-/tmp/venv-mitsuba}
SHARED=../shared
MI_SCENE=$SHARED/models/cornell-box/mitsuba/cbox-rgb.xml
TOOLS=$SHARED/tools/mitsuba-ref
OUT=${OUT:-target/mitsuba-compare}
mkdir -p "$OUT"
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-$(dpkg -L libllvm19 2>/dev/null | grep 'libLLVM.so.19' | head -1)}
PY=$VENV/bin/python
cargo build --release --bin lightpath -q
LP=./target/release/lightpath
REF_SPP=${REF_SPP:-4096}

mitsuba() { # variant spp out.exr -> prints seconds
    "$PY" "$TOOLS/render.py" "$MI_SCENE" --spp "$2" --variant "$1" --threads 2 \
        -D max_depth=8 -D res=256 -o "$3" --json "$3.json" >/dev/null 2>&1
    "$PY" -c "import json,sys; d=json.load(open(sys.argv[1])); print(d['render_s'])" "$3.json"
}
# lightpath renders Mitsuba's own scene file (our Mitsuba 3 reader), so both renderers
# run the same scene with the same path tracer settings (rr_depth 5, box pixel filter);
# only the sampler is ours to choose.
lightpath() { # sampler spp out.exr -> prints seconds
    "$LP" render "$MI_SCENE" -D spp="$2" -D max_depth=8 -D res=256 --sampler "$1" \
        --threads 2 -o "$3" -q --stats-json "$3.json"
    "$PY" -c "import json,sys; print(json.load(open(sys.argv[1]))['seconds']['render'])" "$3.json"
}
relmse() {
    "$PY" "$TOOLS/compare.py" "$1" "$OUT/ref.exr" | sed -n 's/.*relMSE=\([0-9.e-]*\).*/\1/p'
}

[ -f "$OUT/ref.exr" ] || { echo "reference: mitsuba llvm_ad_rgb, $REF_SPP spp"; mitsuba llvm_ad_rgb "$REF_SPP" "$OUT/ref.exr" >/dev/null; }
mitsuba llvm_ad_rgb 16 "$OUT/warmup.exr" >/dev/null   # JIT cache

# This machine's speed drifts by 10-20% within minutes: the timed renders alternate
# between the renderers for $ROUNDS rounds and each row reports the median time.
ROUNDS=${ROUNDS:-3}
median() { tr ' ' '\n' | grep . | sort -g | awk '{a[NR]=$1} END {print (NR%2) ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2}'; }
T_LLVM="" T_SCALAR="" T_IND="" T_SOBOL=""
for r in $(seq "$ROUNDS"); do
    T_LLVM="$T_LLVM $(mitsuba llvm_ad_rgb 64 "$OUT/mi-llvm.exr")"
    T_IND="$T_IND $(lightpath independent 64 "$OUT/lp-independent.exr")"
    T_SOBOL="$T_SOBOL $(lightpath sobol 64 "$OUT/lp-sobol.exr")"
    T_SCALAR="$T_SCALAR $(mitsuba scalar_rgb 16 "$OUT/mi-scalar.exr")"
done
T_MI=$(echo "$T_LLVM" | median)

printf "%-34s %6s %9s %12s %10s\n" "renderer (median of $ROUNDS)" spp seconds "Msamples/s" relMSE
row() { printf "%-34s %6s %9.3f %12.3f %10.3e\n" "$1" "$2" "$3" "$(echo "$2 * 65536 / $3 / 1000000" | bc -l)" "$4"; }
row "mitsuba llvm_ad_rgb" 64 "$T_MI" "$(relmse "$OUT/mi-llvm.exr")"
row "mitsuba scalar_rgb" 16 "$(echo "$T_SCALAR" | median)" "$(relmse "$OUT/mi-scalar.exr")"
for s in independent sobol; do
    if [ $s = independent ]; then TS=$T_IND; else TS=$T_SOBOL; fi
    T=$(echo "$TS" | median)
    row "lightpath $s" 64 "$T" "$(relmse "$OUT/lp-$s.exr")"
    # Equal time: as many samples as fit in Mitsuba llvm's 64-spp time (median), first
    # estimated from the 64-spp speed, then fewer while the render takes longer than
    # Mitsuba's (the same for both samplers: an Owen-scrambled Sobol prefix of any
    # length is unbiased, though powers of two stratify best and shuffle fastest).
    # For Sobol the largest power of two that fits is rendered too.
    SPP=$(echo "64 * $T_MI / $T" | bc -l | awk '{n=int($1+0.5); if(n<1)n=1; print n}')
    while :; do
        T2=$(lightpath $s "$SPP" "$OUT/lp-$s-eq.exr")
        if [ "$SPP" -le 1 ] || [ "$(echo "$T2 <= $T_MI" | bc -l)" = 1 ]; then break; fi
        SPP=$((SPP - 1))
    done
    row "lightpath $s (equal time)" "$SPP" "$T2" "$(relmse "$OUT/lp-$s-eq.exr")"
    if [ $s = sobol ]; then
        P=1; while [ $((P * 2)) -le "$SPP" ]; do P=$((P * 2)); done
        if [ "$P" != "$SPP" ]; then
            T2=$(lightpath $s "$P" "$OUT/lp-$s-eq2.exr")
            row "lightpath $s (equal time, 2^k)" "$P" "$T2" "$(relmse "$OUT/lp-$s-eq2.exr")"
        fi
    fi
done

# Each round's times, and the speed ratio (Mitsuba llvm's time over lightpath's) of each
# round and of the fastest runs: a sitting's medians move with the machine's drift, so
# these show how much of a sitting's ratio is the drift.
echo "rounds (seconds): mitsuba llvm:$T_LLVM | lightpath independent:$T_IND | lightpath sobol:$T_SOBOL"
"$PY" - "$T_LLVM" "$T_IND" <<'PY'
import sys, statistics as st
mi = [float(x) for x in sys.argv[1].split()]
lp = [float(x) for x in sys.argv[2].split()]
r = [m / l for m, l in zip(mi, lp)]
print("independent over llvm_ad_rgb, per round: " + " ".join(f"{x:.3f}" for x in r)
      + f"  (median {st.median(r):.3f}; fastest runs {min(mi) / min(lp):.3f})")
PY
