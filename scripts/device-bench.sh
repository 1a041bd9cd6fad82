#!/usr/bin/env bash
# The GPU measurements of BENCHMARKS.md (volumes, cuts, surfaces, gradient solids, PTM and lapped
# renders) in one run, for a machine with a hardware GPU but no Rust toolchain (the device tool's
# lent H100): it runs the carried release binaries and writes each table to $OUT (or ./out).
#
# Prepare on the build machine (see BENCHMARKS.md, "Measuring on a lent GPU"):
#   scripts/device-bench.sh --prepare      # strips the binaries into dist/, copies the bunny
# then on the GPU machine, from the repository root (dist/ and .gl/ carried):
#   scripts/device-bench.sh [--quick] [PHASE...]
# PHASEs (default: all, in this order): kernels compare synth cuts surface gradient other. One device
# call may run 10 minutes: split the phases over calls where they would not fit.
# --quick runs small sizes and few repeats only (a check of the script itself, e.g. on lavapipe).
set -uo pipefail
cd "$(dirname "$0")/.."

if [[ "${1:-}" == "--prepare" ]]; then
    set -e
    cargo build --release --locked
    kernels=$(cargo test --release --locked --test kernels --no-run --message-format=json 2>/dev/null |
        grep -o '"executable":"[^"]*kernels-[^"]*"' | head -1 | cut -d'"' -f4)
    mkdir -p dist
    strip -o dist/solidsynth target/release/solidsynth
    strip -o dist/kernels-test "$kernels"
    cp assets/meshes/bunny.obj dist/bunny.obj
    rm -rf dist/ablations
    scripts/correct-ablations.sh dist/ablations
    ls -la dist
    exit 0
fi

quick=0
if [[ "${1:-}" == "--quick" ]]; then
    quick=1
    shift
fi
phases=("$@")
((${#phases[@]})) || phases=(kernels compare synth cuts surface gradient other)
wants() { [[ " ${phases[*]} " == *" $1 "* ]]; }
# shellcheck source=scripts/device-env.sh
source scripts/device-env.sh
ss=dist/solidsynth
work=$(mktemp -d)

# Each section's output goes to its own file (the tool returns at most 8).
section() {
    local file=$1
    shift
    echo "== $*" | tee -a "$out/$file"
    "$@" 2>&1 | tee -a "$out/$file"
    echo "   (exit ${PIPESTATUS[0]})" | tee -a "$out/$file"
}

{
    date -u
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1
    nproc
    $ss adapters
} >"$out/machine.txt" 2>&1
cat "$out/machine.txt"

if ((quick)); then
    both_sizes=32
    gpu_sizes=64
    cut_sizes="128"
    repeat=3
    resolutions="128"
    fast_resolution=128
    render_sizes=64
    gradient_sizes=32
    runs=1
    ablation_size=32
else
    both_sizes=64,128,256
    gpu_sizes=512
    cut_sizes="128 256 512"
    repeat=20
    resolutions="256 512 1024 2048"
    fast_resolution=1024
    render_sizes=64,128,256
    gradient_sizes=64,128
    runs=3
    ablation_size=256
fi

# Byte-exactness of every kernel against its CPU reference, on this device.
wants kernels && section kernels.txt dist/kernels-test

# Issue 55's table: the same jobs on the CPU backend and on every adapter, and the same bytes.
if wants compare; then
    compare_flags=()
    ((quick)) && compare_flags=(--quick)
    section compare.md $ss --quiet bench compare "${compare_flags[@]}"
fi

# Issue 4: full volumes (targets 256^3 <= 100 ms, 512^3 <= 1 s on an H100); the CPU backend
# beside it up to 256^3 for the per-kernel ratios.
if wants synth; then
    section synth.txt $ss bench synth --sizes $both_sizes --backends gpu,cpu --runs $runs
    section synth.txt $ss bench synth --sizes $gpu_sizes --backends gpu --runs $runs
    # One pass at the finest level (README: --passes), the faster schedule.
    section synth.txt $ss bench synth --sizes $both_sizes,$gpu_sizes --backends gpu --runs $runs \
        --passes 2,2,2,1
    # `correct`'s k-major blocks of 32 bricks, a warp (8 by default on a GPU: `block_bricks` in
    # src/gpu/correct.rs).
    section synth.txt env SOLIDSYNTH_BLOCK_BRICKS=32 $ss bench synth --sizes $gpu_sizes \
        --backends gpu --runs $runs
    # What each part of `correct` costs here: timing-only variants (scripts/correct-ablations.sh,
    # made by --prepare), the second of two runs each (the first compiles the variant).
    for v in "" dist/ablations/*; do
        for run in 1 2; do
            SOLIDSYNTH_SHADER_DIR=$v $ss synth --size "$ablation_size" --backend gpu --profile \
                -o "$work/ablation.nrrd" >"$work/ablation.txt" 2>&1
        done
        echo "== correct kernel, ${v:-as built}: $(grep -E '^ *kernel correct +[0-9]' "$work/ablation.txt")" |
            tee -a "$out/synth.txt"
    done
fi

# Issue 5: warm cut latency (target 256^2 <= 2 ms) and the bunny (target <= 1 s at 1024).
if wants cuts; then
    for s in $cut_sizes; do
        for cache in "--coarse-cache 128" ""; do
            # An oblique plane (brick-level plan) and an axis-aligned slice (voxel-exact plan).
            for normal in 0.3,0.5,0.8 0,0,1; do
                # shellcheck disable=SC2086
                section cuts.txt $ss cut --backend gpu --origin 32,32,20 --normal $normal \
                    --size "$s" --repeat $repeat $cache -o "$work/cut$s.png"
            done
        done
        # One finest pass, the faster schedule.
        section cuts.txt $ss cut --backend gpu --origin 32,32,20 --normal 0,0,1 --size "$s" \
            --repeat $repeat --coarse-cache 128 --passes 2,2,2,1 -o "$work/cut$s.png"
    done
    # Where a fast cut's time goes besides the kernels: the host's debug timings (plan, brick
    # index, the wait for the device and the copy), then each kernel's GPU time.
    section cuts.txt env SOLIDSYNTH_LOG=solidsynth=debug $ss cut --backend gpu \
        --origin 32,32,20 --normal 0,0,1 --size 256 --repeat 4 --coarse-cache 128 \
        --passes 2,2,2,1 -o "$work/cut-debug.png"
    section cuts.txt $ss cut --backend gpu --origin 32,32,20 --normal 0,0,1 --size 256 \
        --repeat $repeat --coarse-cache 128 --passes 2,2,2,1 --profile -o "$work/cut-profile.png"
    # `correct`'s blocks of 8 (the default) and 32 bricks, one after the other.
    for bricks in 8 32; do
        section cuts.txt env SOLIDSYNTH_BLOCK_BRICKS=$bricks $ss cut --backend gpu \
            --origin 32,32,20 --normal 0,0,1 --size 256 --repeat $repeat \
            --coarse-cache 128 --passes 2,2,2,1 -o "$work/cut-blocks.png"
    done
fi
if wants surface; then
    for r in $resolutions; do
        section surface.txt $ss surface --backend gpu --mesh dist/bunny.obj --resolution "$r" \
            --json -o "$work/bunny$r.glb"
    done
    # The issue's resolution with one finest pass and the coarse cache.
    section surface.txt $ss surface --backend gpu --mesh dist/bunny.obj \
        --resolution "$fast_resolution" --coarse-cache 128 --max-group 128 --passes 2,2,2,1 \
        --json -o "$work/bunny-fast.glb"
    section surface.txt env SOLIDSYNTH_BLOCK_BRICKS=32 $ss surface --backend gpu \
        --mesh dist/bunny.obj --resolution "$fast_resolution" --coarse-cache 128 \
        --max-group 128 --passes 2,2,2,1 --json -o "$work/bunny-fast-blocks32.glb"
fi

# Issue 6: tricubic rendering (target 256^3 <= 5 ms) and direct synthesis.
if wants gradient; then
    section gradient.txt $ss bench gradient-render --sizes $render_sizes --runs 5
    section gradient.txt $ss bench gradient-synth --sizes $gradient_sizes --backends gpu,cpu \
        --runs 1
fi

# PTM relighting and the lapped render.
if wants other; then
    section other.txt $ss bench ptm --runs $runs
    section other.txt $ss bench lapped --runs $runs --cuts $repeat --render
fi

rm -rf "$work"
ls -la "$out"
