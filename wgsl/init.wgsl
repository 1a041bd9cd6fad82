// Initialization of the l_start level: tiling of exemplar 0's candidate slab (5 voxels thick
// along x), warped by the jitter field; or, with `cache_period` n > 0, level L-1 read from the
// coarse-level cache (a periodic n^3 volume of triples) at the warped position. CPU reference:
// src/cpu/init.rs and src/lazy/jitter.rs.

struct InitParams {
    ex: ExemplarFields,
    list_offset: u32, list_count: u32, grid_stride: u32,
    period: u32, cache_period: u32,
    seed_lo: u32, seed_hi: u32,
    jitter_on: u32,
    tile_x: u32, tile_y: u32, tile_z: u32,
    slab_offset: u32,
    amp0: i32, amp1: i32, amp2: i32, amp3: i32,
    sig0: i32, sig1: i32, sig2: i32, sig3: i32,
}

const CELL: i32 = 4;
const REACH: i32 = 2;
const WEIGHT_ENTRIES: i32 = 144;

@group(0) @binding(0) var<uniform> params: InitParams;
// (binding 1: level data, declared by the prelude)
// 144 Gaussian weights, then 64 unit directions (xyz, 1/256 units, as i32 bits).
@group(0) @binding(2) var<storage, read> table: array<u32>;
@group(0) @binding(3) var<storage, read_write> out_state: array<u32>;
// (binding 4: the level's brick index, declared by the prelude)
// The coarse-level cache's triples, 3 words per voxel, x fastest (any buffer when not used).
@group(0) @binding(5) var<storage, read> cache: array<u32>;

fn cell_hash(cell: vec3<i32>) -> u32 {
    // Tileable solids: cells repeat with the period, so the field does too.
    var c = cell;
    if (params.period != 0u) {
        let n = i32(params.period) / CELL;
        c = vec3<i32>(rem_euclid(c.x, n), rem_euclid(c.y, n), rem_euclid(c.z, n));
    }
    var h = hash32(params.seed_lo ^ 0x9E3779B9u);
    h = hash32(h ^ params.seed_hi);
    h = hash32(h ^ bitcast<u32>(c.x));
    h = hash32(h ^ bitcast<u32>(c.y));
    h = hash32(h ^ bitcast<u32>(c.z));
    return h;
}

// The Gaussians of the 5^3 cells around this workgroup's cell (its brick: bricks and jitter
// cells are both 4^3 and aligned), computed once per workgroup instead of once per voxel (the
// CPU reference likewise shares them per cell: src/lazy/jitter.rs, cell_gaussians). Each:
// centre (1/256 voxels), then shape | direction << 2.
// Only those that reach some voxel of the cell are kept (as the reference's cell_gaussians:
// the others add exactly zero), in whatever order the threads append them: the warp is an
// integer sum, the same in any order. About a fifth of the 125 are kept, so each voxel's loop is
// that much shorter.
const CELLS_AROUND: u32 = 125u;
var<workgroup> gaussians: array<vec4<i32>, CELLS_AROUND>;
var<workgroup> kept: atomic<u32>;

fn gaussian_of(cell: vec3<i32>) -> vec4<i32> {
    let h = cell_hash(cell);
    let shape = hash32(h ^ 4u);
    return vec4<i32>(
        cell.x * CELL * 256 + i32(hash32(h ^ 1u) & 1023u),
        cell.y * CELL * 256 + i32(hash32(h ^ 2u) & 1023u),
        cell.z * CELL * 256 + i32(hash32(h ^ 3u) & 1023u),
        i32((shape & 3u) | (((shape >> 2u) & 63u) << 2u)),
    );
}

// floor(r2 / sig2) for 0 <= r2 < 2^24 and sig2 > 0, through f32 (an integer division runs lane by
// lane on SIMD drivers such as lavapipe): both operands convert exactly and the quotient's error
// is well under 1, so one step either way makes it exact.
fn floor_div(r2: i32, sig2: i32) -> i32 {
    var q = i32(f32(r2) / f32(sig2));
    q -= select(0, 1, q * sig2 > r2);
    q += select(0, 1, (q + 1) * sig2 <= r2);
    return q;
}

fn jitter_offset(p: vec3<i32>) -> vec3<i32> {
    var amps = array<i32, 4>(params.amp0, params.amp1, params.amp2, params.amp3);
    var sig2 = array<i32, 4>(params.sig0, params.sig1, params.sig2, params.sig3);
    let pos = p * 256 + vec3<i32>(128);
    var disp = vec3<i32>(0);
    let count = atomicLoad(&kept);
    for (var g = 0u; g < count; g++) {
        let gauss = gaussians[g];
        let s = u32(gauss.w) & 3u;
        let dir = u32(gauss.w) >> 2u;
        let d = pos - gauss.xyz;
        let r2 = d.x * d.x + d.y * d.y + d.z * d.z;
        // As the reference: only within the weight table's reach (r2 < 144 sig2 < 2^24).
        if (r2 < WEIGHT_ENTRIES * sig2[s]) {
            let q = floor_div(r2, sig2[s]);
            let t = (amps[s] * i32(table[q])) >> 16u;
            let base = u32(WEIGHT_ENTRIES) + dir * 3u;
            disp += t * vec3<i32>(
                bitcast<i32>(table[base]),
                bitcast<i32>(table[base + 1u]),
                bitcast<i32>(table[base + 2u]),
            );
        }
    }
    return (disp + vec3<i32>(32768)) >> vec3<u32>(16u);
}

@compute @workgroup_size(64)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    // One workgroup per brick (uniform: the Gaussians' barrier needs the whole workgroup).
    let brick = wid.x + wid.y * (params.grid_stride / 64u);
    if (brick >= params.list_count) {
        return;
    }
    let tid = brick * 64u + li;
    let cell = brick_at(params.list_offset, brick);
    let pos = voxel_of(cell, li);
    var warp = vec3<i32>(0);
    if (params.jitter_on != 0u) {
        if (li == 0u) {
            atomicStore(&kept, 0u);
        }
        workgroupBarrier();
        var sig2 = array<i32, 4>(params.sig0, params.sig1, params.sig2, params.sig3);
        // The cell's voxel centres span [lo, lo + 3 voxels] per axis (1/256 voxel).
        let lo = cell * CELL * 256 + vec3<i32>(128);
        for (var g = li; g < CELLS_AROUND; g += 64u) {
            let o = vec3<i32>(vec3<u32>(g % 5u, (g / 5u) % 5u, g / 25u)) - vec3<i32>(REACH);
            let gauss = gaussian_of(cell + o);
            let near = max(max(lo - gauss.xyz, gauss.xyz - (lo + vec3<i32>(3 * 256))), vec3<i32>(0));
            if (dot(near, near) < WEIGHT_ENTRIES * sig2[u32(gauss.w) & 3u]) {
                gaussians[atomicAdd(&kept, 1u)] = gauss;
            }
        }
        workgroupBarrier();
        warp = jitter_offset(pos);
    }
    var q = pos + warp + vec3<i32>(i32(params.tile_x), i32(params.tile_y), i32(params.tile_z));
    let stride = 3u + params.ex.pixel_words;
    let i = tid * stride;
    let pixels = vec3<u32>(params.ex.pixels0, params.ex.pixels1, params.ex.pixels2);
    if (params.cache_period != 0u) {
        let n = i32(params.cache_period);
        let c = vec3<u32>(vec3<i32>(rem_euclid(q.x, n), rem_euclid(q.y, n), rem_euclid(q.z, n)));
        let src = ((c.z * u32(n) + c.y) * u32(n) + c.x) * 3u;
        let t = vec3<u32>(cache[src], cache[src + 1u], cache[src + 2u]);
        out_state[i] = t.x;
        out_state[i + 1u] = t.y;
        out_state[i + 2u] = t.z;
        for (var wd = 0u; wd < params.ex.pixel_words; wd++) {
            out_state[i + 3u + wd] = value_word(t, wd, pixels, params.ex.width, params.ex.pixel_words, params.ex.channels);
        }
        return;
    }
    if (params.period != 0u) {
        let n = i32(params.period);
        q = vec3<i32>(rem_euclid(q.x, n), rem_euclid(q.y, n), rem_euclid(q.z, n));
    }
    let w = params.ex.width;
    let h = params.ex.height;
    // Each 5-voxel layer of slabs along x gets its own hashed (y, z) offset (see the CPU reference).
    let layer = q.x / 5 - select(0, 1, q.x % 5 < 0); // floor division
    let shift = hash32(hash32(params.seed_lo ^ 0x5EEDu) ^ bitcast<u32>(layer));
    let u = u32(rem_euclid(q.y + i32(shift % w), i32(w)));
    let v = u32(rem_euclid(q.z + i32((shift >> 16u) % h), i32(h)));
    let depth = rem_euclid(q.x, 5) - 2;
    let s = params.slab_offset + (v * w + u) * 3u;
    let c1 = level[s + 1u];
    let c2 = level[s + 2u];
    let t = vec3<u32>(
        pack_coord(u, v),
        pack_resolved(coord_x(c1), coord_y(c1) + depth, w, h, params.ex.border),
        pack_resolved(coord_x(c2) + depth, coord_y(c2), w, h, params.ex.border),
    );
    out_state[i] = t.x;
    out_state[i + 1u] = t.y;
    out_state[i + 2u] = t.z;
    for (var wd = 0u; wd < params.ex.pixel_words; wd++) {
        out_state[i + 3u + wd] = value_word(t, wd, pixels, w, params.ex.pixel_words, params.ex.channels);
    }
}
