// Voxel colours of an output box, colour channels packed into one u32: the voxel's cached value
// (the rounded mean of its three exemplar pixels), or, on request, the pixel of one exemplar at
// the voxel's coordinate in it. CPU reference: src/cpu/colorize.rs.

struct ColorizeParams {
    lo_x: i32, lo_y: i32, lo_z: i32,
    size_x: u32, size_y: u32, size_z: u32,
    out_lo_x: i32, out_lo_y: i32, out_lo_z: i32,
    out_size_x: u32, out_size_y: u32, out_size_z: u32,
    color_channels: u32, pixel_words: u32,
    source: u32, ex_width: u32,
    pixels0: u32, pixels1: u32, pixels2: u32, _pad: u32,
}

@group(0) @binding(0) var<uniform> params: ColorizeParams;
// (binding 1: level data, declared by the prelude)
@group(0) @binding(2) var<storage, read> state: array<u32>;
@group(0) @binding(3) var<storage, read_write> colors: array<u32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.out_size_x || gid.y >= params.out_size_y || gid.z >= params.out_size_z) {
        return;
    }
    let pos = vec3<i32>(params.out_lo_x, params.out_lo_y, params.out_lo_z) + vec3<i32>(gid);
    let i = box_index(pos, vec3<i32>(params.lo_x, params.lo_y, params.lo_z),
        vec3<u32>(params.size_x, params.size_y, params.size_z)) * (3u + params.pixel_words);
    // Colour channels are the first ones (at most 4: one word).
    var mask = 0xFFFFFFFFu;
    if (params.color_channels < 4u) {
        mask = (1u << (params.color_channels * 8u)) - 1u;
    }
    var word = state[i + 3u];
    if (params.source != 0u) {
        let a = params.source - 1u;
        let pixels = array<u32, 3>(params.pixels0, params.pixels1, params.pixels2);
        let c = state[i + a];
        word = level[pixels[a] + (u32(coord_y(c)) * params.ex_width + u32(coord_x(c))) * params.pixel_words];
    }
    colors[(gid.z * params.out_size_y + gid.y) * params.out_size_x + gid.x] = word & mask;
}
