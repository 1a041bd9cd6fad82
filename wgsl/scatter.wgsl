// Writes a correction sub-pass's updated voxels back into the state. `correct` reads the state
// and writes its class's voxels to a compact buffer (one stride-word record per listed class
// voxel, in list order), so no invocation reads a value written in the same sub-pass; this kernel
// then copies the needed records into place. The compact buffer is at most an eighth of the
// state (a second full state, copied back after every sub-pass, used to double it; since session
// 25 a copy of the state taken once per pass does, for the brick-local reads of other bricks).
// CPU reference: src/cpu/scatter.rs.

struct ScatterParams {
    grid_lo_x: i32, grid_lo_y: i32, grid_lo_z: i32,
    grid_x: u32, grid_y: u32, grid_z: u32,
    table_offset: u32,
    list_offset: u32, list_count: u32,
    class_x: u32, class_y: u32, class_z: u32,
    mask_offset: u32, grid_stride: u32,
    /// Words per voxel: 3 + pixel_words.
    stride: u32, _pad: u32,
}

@group(0) @binding(0) var<uniform> params: ScatterParams;
@group(0) @binding(2) var<storage, read> updates: array<u32>;
@group(0) @binding(3) var<storage, read_write> state: array<u32>;
// (binding 4: the level's brick index, declared by the prelude)

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let voxel = class_voxel(gid.x + gid.y * params.grid_stride);
    let b = voxel.x;
    let k = voxel.y;
    if (b >= params.list_count) {
        return;
    }
    let tid = b * 8u + k;
    if (((bricks[params.mask_offset + b / 4u] >> ((b % 4u) * 8u + k)) & 1u) == 0u) {
        return; // not updated in this sub-pass
    }
    let cls = vec3<u32>(params.class_x, params.class_y, params.class_z);
    let pos = brick_at(params.list_offset, b) * 4
        + vec3<i32>(cls + 2u * vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u));
    let slot = voxel_index(pos, vec3<i32>(params.grid_lo_x, params.grid_lo_y, params.grid_lo_z),
        vec3<u32>(params.grid_x, params.grid_y, params.grid_z), params.table_offset);
    if (slot == ABSENT) {
        return; // never expected: updated voxels are stored
    }
    for (var w = 0u; w < params.stride; w++) {
        state[slot * params.stride + w] = updates[tid * params.stride + w];
    }
}
