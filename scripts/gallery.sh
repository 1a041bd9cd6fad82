#!/usr/bin/env bash
# Regenerates every picture of the README's gallery (docs/images/) with the project's own
# commands. Usage: scripts/gallery.sh [SOLIDSYNTH_BINARY]  (default: a release build, made here).
# The exemplars are the project's own (the built-in one) and CC0 images it ships
# (tests/fixtures); the bunny is the Stanford bunny (public domain, assets/meshes/bunny.obj).
# The render of lapped models needs a Vulkan device (lavapipe will do).
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-}
if [ -z "$bin" ]; then
  cargo build --release --locked --quiet --manifest-path "$repo/Cargo.toml"
  bin=$repo/target/release/solidsynth
fi
out=$repo/docs/images
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"
cd "$work"
ss() { echo "solidsynth $*" >&2; "$bin" --quiet "$@"; }

# Exemplars beside three orthogonal slices of their solids (the contact sheet).
ss synth --size 64 --seed 5 --backend cpu -o builtin.nrrd --sheet "$out/builtin-sheet.png"
ss synth "$repo/tests/fixtures/cc0_gravel64.png" --size 64 --seed 5 --backend cpu -o gravel.nrrd --sheet "$out/gravel-sheet.png"
ss synth "$repo/tests/fixtures/cc0_brick64.png" --size 64 --seed 5 --backend cpu -o brick.nrrd --sheet "$out/brick-sheet.png"
# The same two solids coloured by `--color fitted` (the triples, the solid itself, are the same).
ss synth --size 64 --seed 5 --backend cpu --color fitted -o builtin-fitted.nrrd --sheet "$out/builtin-fitted-sheet.png"
ss synth "$repo/tests/fixtures/cc0_brick64.png" --size 64 --seed 5 --backend cpu --color fitted -o brick-fitted.nrrd --sheet "$out/brick-fitted-sheet.png"
# A cut at an angle, far from the origin: the infinite solid, synthesized on demand.
ss cut --origin 1000,-500,77 --normal 1,2,3 --size 192 --seed 5 --backend cpu -o "$out/builtin-oblique-cut.png"
# The bunny's surface baked lazily into its atlas and rendered with it (the library example
# does both: `surface` writes the same atlas into a .glb).
echo "cargo run --release --example 06_render_surface -- bunny.obj bunny-surface.png 256" >&2
(cd "$repo" && cargo run --release --locked --quiet --example 06_render_surface -- \
  assets/meshes/bunny.obj "$out/bunny-surface.png" 256)
# Lapped solid textures: the bunny filled with pasted copies of a tileable solid, rendered.
ss synth --size 32 --tileable --seed 5 --backend cpu -o tile.nrrd
ss lapped fill --mesh "$repo/assets/meshes/bunny.obj" --exemplar tile.nrrd --resolution 10 -o bunny.lst
ss lapped render bunny.lst --camera 30,20 --size 256 -o "$out/bunny-lapped.png"
ss lapped exemplar --kind kiwi --size 32 -o kiwi.nrrd
ss lapped fill --mesh builtin:sphere --exemplar kiwi.nrrd --field "$repo/examples/lapped/kiwi.json" --resolution 8 -o kiwi.lst
ss lapped cut kiwi.lst --origin center --normal 0,0.3,1 --size 192 -o "$out/kiwi-lapped-cut.png"
# A gradient solid synthesized directly, then cut at an angle (tricubic evaluation).
ss gradient synth --size 64 --seed 5 --backend cpu -o gradient.gsolid
ss gradient render gradient.gsolid --normal 1,1,1 --size 192 --backend cpu -o "$out/gradient-cut.png"
# A relightable texture: fitted, synthesized larger by quilting, relit from four directions.
ss ptm capture --size 64 --lights 24 -o capture
ss ptm fit capture -o surface.ptm
ss ptm synth surface.ptm --size 128 -o larger.ptm
ss ptm relight larger.ptm --sweep 4 --backend cpu -o "$out/ptm-relit.png"
du -ch "$out"/*.png | tail -1 >&2
