#!/usr/bin/env bash
# Where the host's time goes in the issues' GPU jobs, from the debug timings
# (SOLIDSYNTH_LOG=solidsynth=debug): synth 256^3 and 512^3, the warm fast cut, the fast bunny.
# Run on the device tool's GPU machine after `scripts/device-bench.sh --prepare` (dist/ and .gl
# carried); one log per job in $OUT, summed by scripts/timings-summary.py here.
set -uo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/device-env.sh
source scripts/device-env.sh
ss=${SS:-dist/solidsynth}
work=$(mktemp -d)
$ss --quiet synth --size 16 -o "$work/warm.nrrd"
debug() {
    local name=$1
    shift
    SOLIDSYNTH_LOG=solidsynth=debug "$@" >"$out/$name.log" 2>&1
    echo "== $name (exit $?): $*" | tee -a "$out/summary.txt"
    tail -3 "$out/$name.log" | tee -a "$out/summary.txt"
}
debug synth256 $ss synth --size 256 --backend gpu --json -o "$work/v.nrrd"
debug synth512 $ss synth --size 512 --backend gpu --json -o "$work/v.nrrd"
debug cut256 $ss cut --backend gpu --origin 32,32,20 --normal 0,0,1 --size 256 --repeat 10 \
    --coarse-cache 128 --passes 2,2,2,1 -o "$work/cut.png"
debug bunny $ss surface --backend gpu --mesh dist/bunny.obj --resolution 1024 --coarse-cache 128 \
    --max-group 128 --passes 2,2,2,1 --json -o "$work/bunny.glb"
for g in 64 256; do
    debug bunny-g$g $ss surface --backend gpu --mesh dist/bunny.obj --resolution 1024 \
        --coarse-cache 128 --max-group $g --passes 2,2,2,1 --json -o "$work/bunny.glb"
done
rm -rf "$work"
