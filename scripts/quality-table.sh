#!/usr/bin/env bash
# The quality table of BENCHMARKS.md: every shared exemplar (and the built-in one) x seeds 1 and 2,
# synthesized at 96^3 on the CPU backend and scored by `eval --json`. One JSON line per solid goes
# to OUT/scores.jsonl; extra synth flags (e.g. `--color fitted`) come after the output folder.
#   scripts/quality-table.sh BIN EXEMPLAR_DIR OUT [synth flags...]
set -euo pipefail
bin=$1 dir=$2 out=$3
shift 3
mkdir -p "$out"
exemplars=("$(cd "$(dirname "$0")/.." && pwd)/assets/default-exemplar.png" "$dir"/*.png)
for ex in "${exemplars[@]}"; do
  name=$(basename "$ex" .png)
  for seed in 1 2; do
    vol="$out/$name-$seed.nrrd"
    start=$(date +%s.%N)
    if [ "$name" = default-exemplar ]; then
      "$bin" synth --size 96 --backend cpu --seed "$seed" -q -o "$vol" "$@"
    else
      "$bin" synth "$ex" --size 96 --backend cpu --seed "$seed" -q -o "$vol" "$@"
    fi
    secs=$(echo "$(date +%s.%N) - $start" | bc)
    "$bin" eval "$ex" "$vol" --json --sheet "$out/$name-$seed-sheet.png" |
      python3 -c 'import json,sys; d=json.load(sys.stdin); d["exemplar"]=sys.argv[1]; d["seed"]=int(sys.argv[2]); d["synth_seconds"]=float(sys.argv[3]); print(json.dumps(d))' "$name" "$seed" "$secs" >> "$out/scores.jsonl"
    rm -f "$vol"
    echo "$name seed $seed: ${secs}s"
  done
done
