// Coordinate inheritance: child (i, j, k) of parent (i/2, j/2, k/2) takes 2 * parent_a + (offset
// along axis a+1, offset along axis a+2). CPU reference: src/cpu/upsample.rs.

struct UpsampleParams {
    parent_lo_x: i32, parent_lo_y: i32, parent_lo_z: i32,
    parent_size_x: u32, parent_size_y: u32, parent_size_z: u32,
    child_lo_x: i32, child_lo_y: i32, child_lo_z: i32,
    child_size_x: u32, child_size_y: u32, child_size_z: u32,
    ex_width: u32, ex_height: u32, border: u32,
    channels: u32, pixel_words: u32, pixels0: u32, pixels1: u32, pixels2: u32,
}

@group(0) @binding(0) var<uniform> params: UpsampleParams;
// (binding 1: the child level's data, declared by the prelude)
@group(0) @binding(2) var<storage, read> parent: array<u32>;
@group(0) @binding(3) var<storage, read_write> child: array<u32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.child_size_x || gid.y >= params.child_size_y || gid.z >= params.child_size_z) {
        return;
    }
    let c = vec3<i32>(params.child_lo_x, params.child_lo_y, params.child_lo_z) + vec3<i32>(gid);
    let par = c >> vec3<u32>(1u);
    let o = c - 2 * par;
    let plo = vec3<i32>(params.parent_lo_x, params.parent_lo_y, params.parent_lo_z);
    let psize = vec3<u32>(params.parent_size_x, params.parent_size_y, params.parent_size_z);
    let stride = 3u + params.pixel_words;
    let pi = box_index(par, plo, psize) * stride;
    var offsets = array<vec2<i32>, 3>(vec2<i32>(o.y, o.z), vec2<i32>(o.z, o.x), vec2<i32>(o.x, o.y));
    let ci = ((gid.z * params.child_size_y + gid.y) * params.child_size_x + gid.x) * stride;
    var t: vec3<u32>;
    for (var a = 0u; a < 3u; a++) {
        let pc = parent[pi + a];
        t[a] = pack_resolved(
            2 * coord_x(pc) + offsets[a].x,
            2 * coord_y(pc) + offsets[a].y,
            params.ex_width,
            params.ex_height,
            params.border,
        );
        child[ci + a] = t[a];
    }
    let pixels = vec3<u32>(params.pixels0, params.pixels1, params.pixels2);
    for (var wd = 0u; wd < params.pixel_words; wd++) {
        child[ci + 3u + wd] = value_word(t, wd, pixels, params.ex_width, params.pixel_words, params.channels);
    }
}
