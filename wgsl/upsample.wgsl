// Coordinate inheritance: child (i, j, k) of parent (i/2, j/2, k/2) takes 2 * parent_a + (offset
// along axis a+1, offset along axis a+2). CPU reference: src/cpu/upsample.rs.

struct UpsampleParams {
    ex: ExemplarFields,
    parent_grid_lo_x: i32, parent_grid_lo_y: i32, parent_grid_lo_z: i32,
    parent_grid_x: u32, parent_grid_y: u32, parent_grid_z: u32,
    parent_table: u32,
    list_offset: u32, list_count: u32, grid_stride: u32,
    _r0: u32, _r1: u32,
}

@group(0) @binding(0) var<uniform> params: UpsampleParams;
// (binding 1: the child level's data, declared by the prelude)
@group(0) @binding(2) var<storage, read> parent: array<u32>;
@group(0) @binding(3) var<storage, read_write> child: array<u32>;
// (binding 4: the child level's brick index, with a copy of the parent's table)

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tid = gid.x + gid.y * params.grid_stride;
    if (tid >= params.list_count * 64u) {
        return;
    }
    let c = voxel_of(brick_at(params.list_offset, tid / 64u), tid % 64u);
    let par = c >> vec3<u32>(1u);
    let o = c - 2 * par;
    let plo = vec3<i32>(params.parent_grid_lo_x, params.parent_grid_lo_y, params.parent_grid_lo_z);
    let pdims = vec3<u32>(params.parent_grid_x, params.parent_grid_y, params.parent_grid_z);
    let stride = 3u + params.ex.pixel_words;
    // The plan stores every parent; a missing one (never expected) reads as coordinate 0.
    let pslot = voxel_index(par, plo, pdims, params.parent_table);
    var offsets = array<vec2<i32>, 3>(vec2<i32>(o.y, o.z), vec2<i32>(o.z, o.x), vec2<i32>(o.x, o.y));
    let ci = tid * stride;
    var t: vec3<u32>;
    for (var a = 0u; a < 3u; a++) {
        var pc = 0u;
        if (pslot != ABSENT) {
            pc = parent[pslot * stride + a];
        }
        // Within [0, 2 * parent size), at most one pixel past the child level's edge.
        t[a] = pack_coord(
            resolve_near(2 * coord_x(pc) + offsets[a].x, params.ex.width, params.ex.border),
            resolve_near(2 * coord_y(pc) + offsets[a].y, params.ex.height, params.ex.border),
        );
        child[ci + a] = t[a];
    }
    let pixels = vec3<u32>(params.ex.pixels0, params.ex.pixels1, params.ex.pixels2);
    for (var wd = 0u; wd < params.ex.pixel_words; wd++) {
        child[ci + 3u + wd] = value_word(t, wd, pixels, params.ex.width, params.ex.pixel_words, params.ex.channels);
    }
}
