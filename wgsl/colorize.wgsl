// Voxel colours of an output box, colour channels packed into one u32. Each channel c comes from
// the source in bits 4c..4c+3 of params.source: 0 the voxel's cached value (the rounded mean of
// its three exemplar pixels), a + 1 the pixel of exemplar a at the voxel's coordinate in it, 4 the
// cached value mapped through the `--color matched` table (src/lazy/color_match.rs).
// CPU reference: src/cpu/colorize.rs.

struct ColorizeParams {
    ex: ExemplarFields,
    grid_lo_x: i32, grid_lo_y: i32, grid_lo_z: i32,
    grid_x: u32, grid_y: u32, grid_z: u32,
    table_offset: u32,
    list_offset: u32, list_count: u32, grid_stride: u32,
    match_table: u32, color_channels: u32, source: u32,
    _r0: u32, _r1: u32, _r2: u32,
}

@group(0) @binding(0) var<uniform> params: ColorizeParams;
// (binding 1: level data, declared by the prelude)
@group(0) @binding(2) var<storage, read> state: array<u32>;
@group(0) @binding(3) var<storage, read_write> colors: array<u32>;
// (binding 4: the level's brick index, declared by the prelude)

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tid = gid.x + gid.y * params.grid_stride;
    if (tid >= params.list_count * 64u) {
        return;
    }
    let pos = voxel_of(brick_at(params.list_offset, tid / 64u), tid % 64u);
    let slot = voxel_index(pos, vec3<i32>(params.grid_lo_x, params.grid_lo_y, params.grid_lo_z),
        vec3<u32>(params.grid_x, params.grid_y, params.grid_z), params.table_offset);
    if (slot == ABSENT) {
        colors[tid] = 0u; // never expected: output bricks are stored
        return;
    }
    let i = slot * (3u + params.ex.pixel_words);
    // Colour channels are the first ones (at most 4: one word).
    var mask = 0xFFFFFFFFu;
    if (params.color_channels < 4u) {
        mask = (1u << (params.color_channels * 8u)) - 1u;
    }
    let value = state[i + 3u];
    let pixels = array<u32, 3>(params.ex.pixels0, params.ex.pixels1, params.ex.pixels2);
    var word = 0u;
    for (var c = 0u; c < 4u; c++) {
        let code = (params.source >> (c * 4u)) & 0xFu;
        var picked = value;
        if (code == 4u) {
            // Byte c of table word k: channel c's output for value k.
            picked = level[params.match_table + ((value >> (c * 8u)) & 0xFFu)];
        } else if (code != 0u) {
            let a = code - 1u;
            let t = state[i + a];
            picked = level[pixels[a] + (u32(coord_y(t)) * params.ex.width + u32(coord_x(t))) * params.ex.pixel_words];
        }
        word |= picked & (0xFFu << (c * 8u));
    }
    colors[tid] = word & mask;
}
