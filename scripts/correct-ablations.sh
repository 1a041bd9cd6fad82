#!/usr/bin/env bash
# Timing-only variants of the `correct` kernel, for `SOLIDSYNTH_SHADER_DIR` (README, GPU runtime):
# each skips one part of the correction, so that `synth --profile` on a device shows what that
# part costs there (BENCHMARKS.md). Their outputs differ from the real kernel's by design: time
# them, never use their volumes.
#
#   scripts/correct-ablations.sh OUTDIR
#
# writes OUTDIR/NAME/correct.wgsl (prelude included) for NAME in
#   proj1   the projection reads one neighbour per plane instead of 25 (the default weight
#           layout, halves; with SOLIDSYNTH_WEIGHT_LAYOUT=bytes it is not shortened)
#   no2d    the 2D search looks at the voxel's own candidates only, not its 8 neighbours'
#   no3d    no 3D search (the three best 2D coordinates are taken)
#   empty   the kernel returns before any work (dispatch overhead)
# A pattern that no longer matches the kernel stops the script: update it with the kernel.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: scripts/correct-ablations.sh OUTDIR}

variant() {
    local name=$1
    mkdir -p "$out/$name"
    { cat wgsl/lib/synth_common.wgsl; echo; cat wgsl/correct.wgsl; } |
        FROM=$2 TO=$3 perl -0 -e '
            local $/; my $s = <STDIN>;
            $s =~ s/\Q$ENV{FROM}\E/$ENV{TO}/ or die "correct-ablations: pattern of '"$name"' not found\n";
            print $s;' >"$out/$name/correct.wgsl"
}

variant proj1 \
    $'        for (var dv = -2; dv <= 2; dv++) {\n            for (var du = -2; du <= 2; du++) {\n                add_neighbour(' \
    $'        for (var dv = 0; dv <= 0; dv++) {\n            for (var du = 0; du <= 0; du++) {\n                add_neighbour('
variant no2d \
    $'    for (var dv = -1; dv <= 1; dv++) {\n        for (var du = -1; du <= 1; du++) {\n            // Coordinate a' \
    $'    for (var dv = 0; dv <= 0; dv++) {\n        for (var du = 0; du <= 0; du++) {\n            // Coordinate a'
variant no3d \
    $'    if (params.mode == 0u) {\n        // The voxel\'s current triple' \
    $'    if (false) {\n        // The voxel\'s current triple'
variant empty \
    $'        return; // a voxel the plan does not need\n    }' \
    $'        return; // a voxel the plan does not need\n    }\n    if (params.mode < 7u) {\n        return;\n    }'
echo "correct-ablations: proj1 no2d no3d empty in $out"
