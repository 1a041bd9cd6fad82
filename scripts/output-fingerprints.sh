#!/usr/bin/env bash
# Runs a fixed list of small commands covering every output path (synth, region, cut, surface,
# gradient, ptm, lapped) with one solidsynth binary and writes the outputs to a folder; run it
# with two builds and `diff -r` the folders to prove a change left every byte as it was.
#   scripts/output-fingerprints.sh BINARY OUTDIR [gpu]
# With `gpu`, the lazy-synthesis commands also run on `--backend gpu` (lavapipe or a GPU).
# A fixed seed everywhere; small sizes so the list runs in a few minutes on 2 cores.
set -euo pipefail
bin=$(realpath "$1")
root=$(realpath "$(dirname "$0")/..")
out=$2
gpu=${3:-}
mkdir -p "$out"
cd "$out"
export SOLIDSYNTH_LOG=warn
run() { "$bin" "$@" >/dev/null 2>>log.txt; }

run analyze --seed 1 -o builtin.ssa 2>/dev/null || run analyze -o builtin.ssa
printf 'v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\nf 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n' > octahedron.obj
backends=(cpu)
[ -n "$gpu" ] && backends+=(gpu)
for b in "${backends[@]}"; do
  run synth builtin.ssa --size 40 --seed 5 --backend "$b" -o "synth-$b.nrrd" --triples "synth-$b.triples"
  run synth builtin.ssa --size 32 --tileable --seed 2 --backend "$b" -o "tileable-$b.nrrd"
  run synth builtin.ssa --size 48 --seed 6 --max-group 16 --backend "$b" -o "grouped-$b.nrrd"
  run region builtin.ssa --box=-13,-7,5,19,21,29 --seed 7 --backend "$b" -o "region-$b.nrrd"
  run region builtin.ssa --box=-13,-7,5,19,21,29 --seed 7 --color matched --backend "$b" -o "matched-$b.nrrd"
  run cut builtin.ssa --origin 3,-4,11 --normal 0,0,1 --size 48 --seed 8 --backend "$b" -o "cut-z-$b.png"
  run cut builtin.ssa --origin 3,-4,11 --normal 1,2,3 --size 48 --seed 8 --backend "$b" -o "cut-oblique-$b.png"
  run cut builtin.ssa --origin 0,0,0 --normal 0,1,1 --size 48 --seed 8 --coarse-cache 64 --repeat 2 --backend "$b" -o "cut-cached-$b.png"
  run surface builtin.ssa --mesh octahedron.obj --resolution 48 --texels 5 --seed 3 --backend "$b" -o "surface-$b.glb"
done
# Gradient solids, PTMs and lapped solids (CPU; their GPU kernels are float kernels with
# tolerances, compared by the kernels-tests).
run gradient synth "$root/tests/fixtures/cc0_gravel64.png" --size 18 --iterations 1 --seed 4 --backend cpu -o gradient.gsolid
run gradient render gradient.gsolid --size 20 --backend cpu -o gradient-render.nrrd
run ptm capture --size 40 --lights 12 -o photos
run ptm fit photos --format rgb -o fitted.ptm
run ptm synth fitted.ptm --size 72 --block 16 --overlap 4 --seed 2 -o synthesized.ptm
run ptm relight synthesized.ptm --light 0.5,-0.2 --specular 0.3 --backend cpu -o relit.png
run synth builtin.ssa --size 32 --tileable --seed 2 --backend cpu -o lapped-exemplar.nrrd
run lapped fill --mesh builtin:sphere --exemplar lapped-exemplar.nrrd --resolution 6 --seed 3 -o model.lst
run lapped cut model.lst --origin 0,0,0 --normal 0,0,1 --size 64 --extent 2.5 -o lapped-cut.png
run lapped bake model.lst -o lapped.glb
ls
