// Voxel colours of an output box: the rounded mean of the three exemplar pixels of each voxel's
// triple, colour channels packed into one u32. CPU reference: src/cpu/colorize.rs.

struct ColorizeParams {
    lo_x: i32, lo_y: i32, lo_z: i32,
    size_x: u32, size_y: u32, size_z: u32,
    out_lo_x: i32, out_lo_y: i32, out_lo_z: i32,
    out_size_x: u32, out_size_y: u32, out_size_z: u32,
    ex_width: u32, channels: u32, color_channels: u32, pixel_words: u32,
    pixels0: u32, pixels1: u32, pixels2: u32, _pad: u32,
}

@group(0) @binding(0) var<uniform> params: ColorizeParams;
@group(0) @binding(1) var<storage, read> level: array<u32>;
@group(0) @binding(2) var<storage, read> state: array<u32>;
@group(0) @binding(3) var<storage, read_write> colors: array<u32>;

fn pixel_byte(base: u32, c: u32, ch: u32) -> u32 {
    let word = level[base + (u32(coord_y(c)) * params.ex_width + u32(coord_x(c))) * params.pixel_words + ch / 4u];
    return (word >> ((ch % 4u) * 8u)) & 0xFFu;
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.out_size_x || gid.y >= params.out_size_y || gid.z >= params.out_size_z) {
        return;
    }
    let pos = vec3<i32>(params.out_lo_x, params.out_lo_y, params.out_lo_z) + vec3<i32>(gid);
    let i = box_index(pos, vec3<i32>(params.lo_x, params.lo_y, params.lo_z),
        vec3<u32>(params.size_x, params.size_y, params.size_z)) * 3u;
    var packed = 0u;
    for (var ch = 0u; ch < params.color_channels; ch++) {
        let sum = pixel_byte(params.pixels0, state[i], ch)
            + pixel_byte(params.pixels1, state[i + 1u], ch)
            + pixel_byte(params.pixels2, state[i + 2u], ch);
        packed |= ((sum + 1u) / 3u) << (ch * 8u);
    }
    colors[(gid.z * params.out_size_y + gid.y) * params.out_size_x + gid.x] = packed;
}
