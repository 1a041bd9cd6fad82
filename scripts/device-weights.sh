#!/usr/bin/env bash
# The two layouts of 16-bit projection weights in `correct` (`SOLIDSYNTH_WEIGHT_LAYOUT`, see
# wgsl/correct.wgsl's `ProjectionWeights`) timed alternately on one device: the default halves
# (16-bit multiply-adds, the fastest on lavapipe) against bytes (packed byte dot products, which
# a GPU with a native 4x8-bit dot product may run faster; 1.3-1.4x slower on lavapipe). Each run
# must give the same bytes; the script compares them and says so.
#
# On the device tool's GPU machine after `scripts/device-bench.sh --prepare` (dist/ and .gl
# carried), from the repository root:
#   scripts/device-weights.sh [ROUNDS]      (default 3; about 1 minute per round on an H100)
# Writes $OUT/weights.txt: per run the `correct` kernel time (`--profile`) and the wall time.
# Locally, through lavapipe: SS="scripts/lavapipe-sid.sh run dist/solidsynth" SIZES=64,128 ...
set -uo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/device-env.sh
source scripts/device-env.sh
ss=${SS:-dist/solidsynth}
rounds=${1:-3}
IFS=, read -ra sizes <<<"${SIZES:-256,512}"
work=$(mktemp -d)
log="$out/weights.txt"
$ss --quiet synth --size 16 -o "$work/warm.nrrd"
run() {
    local layout=$1 name=$2
    shift 2
    local start end
    start=$(date +%s%N)
    SOLIDSYNTH_WEIGHT_LAYOUT=$layout $ss "$@" >"$work/run.log" 2>&1
    local rc=$?
    end=$(date +%s%N)
    printf '%-7s %-10s exit %d  wall %d ms  %s\n' "$layout" "$name" "$rc" \
        $(((end - start) / 1000000)) "$(grep -E 'kernel correct|median' "$work/run.log" | tr -s ' ' | tr '\n' ' ')" |
        tee -a "$log"
}
for ((r = 1; r <= rounds; r++)); do
    for layout in halves bytes; do
        for n in "${sizes[@]}"; do
            run "$layout" "synth$n" synth --size "$n" --backend gpu --profile -o "$work/$layout-$n.nrrd"
        done
        run "$layout" cut256 cut --backend gpu --origin 32,32,20 --normal 0,0,1 --size 256 \
            --repeat 20 --coarse-cache 128 --passes 2,2,2,1 -o "$work/$layout-cut.png"
    done
done
for n in "${sizes[@]}"; do
    cmp "$work/halves-$n.nrrd" "$work/bytes-$n.nrrd" && echo "synth $n: same bytes" | tee -a "$log"
done
cmp "$work/halves-cut.png" "$work/bytes-cut.png" && echo "cut: same bytes" | tee -a "$log"
rm -rf "$work"
