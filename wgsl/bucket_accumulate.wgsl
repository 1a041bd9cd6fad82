// Bucket accumulation of gradient-solid synthesis (paper 4.2.5): matched patch samples scattered
// into per-voxel buckets. Pass 0 counts samples per (voxel, colour cluster); pass 1 finds each
// voxel's two dominant clusters (most samples, ties to the lower cluster id), once per voxel;
// pass 2 sums, in fixed point, the channels of the samples of those two clusters. Integer
// atomics: the result does not depend on the order in which samples arrive, and equals the CPU
// reference bit for bit (src/cpu/bucket_accumulate.rs).

struct BucketParams {
    samples: u32, clusters: u32, channels: u32, pass_index: u32,
    grid_stride: u32, voxels: u32, _pad1: u32, _pad2: u32,
}

const MAX_CLUSTERS: u32 = 32u;
// A voxel's dominant pair, first | second << 16; NONE for a missing one.
const NONE: u32 = 0xFFFFu;

@group(0) @binding(0) var<uniform> params: BucketParams;
// Per sample: voxel index, cluster id, then `channels` values (0..=255).
@group(0) @binding(1) var<storage, read> samples: array<u32>;
// Per voxel: `clusters` counts.
@group(0) @binding(2) var<storage, read_write> counts: array<atomic<u32>>;
// Per voxel: for its first then second dominant cluster, a sample count and `channels` sums.
@group(0) @binding(3) var<storage, read_write> sums: array<atomic<u32>>;
// Per voxel: its dominant pair (pass 1 writes, pass 2 reads).
@group(0) @binding(4) var<storage, read_write> dominants: array<u32>;

// The two clusters with most samples at `voxel` (ties to the lower id; a cluster without
// samples is never dominant: NONE).
fn dominant(voxel: u32) -> u32 {
    var first = NONE;
    var second = NONE;
    var n1 = 0u;
    var n2 = 0u;
    for (var c = 0u; c < params.clusters; c++) {
        let n = atomicLoad(&counts[voxel * params.clusters + c]);
        if (n > n1) {
            second = first;
            n2 = n1;
            first = c;
            n1 = n;
        } else if (n > n2) {
            second = c;
            n2 = n;
        }
    }
    return first | (second << 16u);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tid = gid.x + gid.y * params.grid_stride;
    if (params.pass_index == 1u) {
        if (tid < params.voxels) {
            dominants[tid] = dominant(tid);
        }
        return;
    }
    if (tid >= params.samples) {
        return;
    }
    let stride = 2u + params.channels;
    let s = tid * stride;
    let voxel = samples[s];
    let cluster = samples[s + 1u];
    if (cluster >= params.clusters) {
        return; // malformed sample: ignored on both backends
    }
    if (params.pass_index == 0u) {
        atomicAdd(&counts[voxel * params.clusters + cluster], 1u);
        return;
    }
    let d = dominants[voxel];
    var slot = 2u;
    if (cluster == (d & NONE)) {
        slot = 0u;
    } else if (cluster == (d >> 16u)) {
        slot = 1u;
    }
    if (slot == 2u) {
        return;
    }
    let base = (voxel * 2u + slot) * (1u + params.channels);
    atomicAdd(&sums[base], 1u);
    for (var c = 0u; c < params.channels; c++) {
        // Fixed point 8.8: exact for values 0..=255 (stored as value << 8).
        atomicAdd(&sums[base + 1u + c], min(samples[s + 2u + c], 255u) << 8u);
    }
}
