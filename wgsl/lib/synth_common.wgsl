// Helpers shared by the synthesis kernels (prepended to init, upsample, correct and colorize by
// src/gpu/shaders.rs). CPU counterparts: src/cpu/synth_common.rs, src/util/hash.rs.
//
// Every synthesis kernel binds the level's packed exemplar data at @binding(1) (kernels that do
// not use it leave it out of their layout). A state holds per voxel its triple (3 words), then
// its value, the mean of its three exemplar pixels (pixel_words words): stride 3 + pixel_words.

@group(0) @binding(1) var<storage, read> level: array<u32>;

// The level's exemplar fields, the first member of every synthesis kernel's uniforms
// (`ExemplarFields` in src/contract/uniforms.rs, built once per level by `ExemplarFields::of`):
// exemplar size, border (0 wrap, 1 mirror), working channels, words per pixel, and each
// exemplar's pixels' word offset in the level data.
struct ExemplarFields {
    width: u32, height: u32, border: u32, channels: u32,
    pixel_words: u32, pixels0: u32, pixels1: u32, pixels2: u32,
}
// The level's brick index (src/contract/bricks.rs, planned by src/lazy/bricks.rs): brick tables (one word per brick of a grid's
// bounding box: its slot, or ABSENT) and brick lists (three i32 words per brick).
@group(0) @binding(4) var<storage, read> bricks: array<u32>;

const ABSENT: u32 = 0xFFFFFFFFu;

// Border::resolve: 0 = wrap, 1 = mirror (reflect-101).
fn resolve(c: i32, len: u32, border: u32) -> u32 {
    let n = i32(len);
    if (c >= -1 && c <= n) {
        return resolve_near(c, len, border);
    }
    if (border == 0u) {
        return u32(((c % n) + n) % n);
    }
    if (n == 1) {
        return 0u;
    }
    let period = 2 * (n - 1);
    let m = ((c % period) + period) % period;
    if (m >= n) {
        return u32(period - m);
    }
    return u32(m);
}

// `resolve` for a coordinate at most one pixel outside the exemplar (c in [-1, len]), without
// `resolve`'s general fallback: SIMD drivers such as lavapipe execute both sides of a branch
// even when no lane takes one, so that fallback's integer divisions ran lane by lane for every
// call (~8% of the correction kernel). CPU counterpart: `resolve` (the same values in that range).
fn resolve_near(c: i32, len: u32, border: u32) -> u32 {
    let n = i32(len);
    if (border == 0u) {
        return u32(select(select(c, c - n, c >= n), c + n, c < 0));
    }
    // Mirror (reflect-101); a 1-pixel exemplar resolves everything to 0.
    return u32(clamp(select(select(c, 2 * (n - 1) - c, c >= n), -c, c < 0), 0, n - 1));
}

fn pack_coord(x: u32, y: u32) -> u32 {
    return x | (y << 16u);
}

fn pack_resolved(x: i32, y: i32, w: u32, h: u32, border: u32) -> u32 {
    return pack_coord(resolve(x, w, border), resolve(y, h, border));
}

fn coord_x(c: u32) -> i32 {
    return i32(c & 0xFFFFu);
}

fn coord_y(c: u32) -> i32 {
    return i32(c >> 16u);
}

// Brick `i` of the list starting at word `list`.
fn brick_at(list: u32, i: u32) -> vec3<i32> {
    let e = list + 3u * i;
    return vec3<i32>(bitcast<i32>(bricks[e]), bitcast<i32>(bricks[e + 1u]), bitcast<i32>(bricks[e + 2u]));
}

// (listed brick b, class voxel k) of thread `thread` of a correction sub-pass (`correct`): a
// block of 8 x `bricks` threads takes `bricks` listed bricks, its threads class voxel k-major
// (thread t is voxel k = t / bricks of brick t % bricks), so the lanes of a SIMD group of up to
// `bricks` lanes sit at the same position in neighbouring bricks (`bricks`: 8, or 16 on a CPU
// device with 16-lane subgroups: `block_bricks` in src/gpu/synth.rs). A thin request needs some
// of a brick's class voxels and not others (a slice's last sub-pass: the four on one z layer),
// mostly the same k in neighbouring bricks, so the voxels the plan skips fill whole SIMD groups,
// which a driver skips. On lavapipe on the 2-core Intel Xeon development machine the warm
// axis-aligned 256^2 and 512^2 cuts got 20-30% faster than with brick-major threads (99.5% of the
// lanes busy instead of 90%, and the lanes' neighbour lookups agree); boxes, oblique cuts and
// surfaces are unchanged within noise (BENCHMARKS.md). The grid's rows are whole workgroups
// (`dispatch_grid`), the host dispatches whole blocks and takes the rows' stride from the same
// thread count (`correct_dispatch`), so this is a bijection.
fn class_voxel(thread: u32, bricks: u32) -> vec2<u32> {
    return vec2<u32>((thread / (8u * bricks)) * bricks + thread % bricks, (thread / bricks) % 8u);
}

// The voxel at `local` (x fastest) in brick `b`.
fn voxel_of(b: vec3<i32>, local: u32) -> vec3<i32> {
    return b * 4 + vec3<i32>(i32(local & 3u), i32((local >> 2u) & 3u), i32(local >> 4u));
}

// Index of voxel p in a state whose brick table (over the bricks grid_lo + [0, dims)) starts at
// word `table`; ABSENT when its brick is not stored.
fn voxel_index(p: vec3<i32>, grid_lo: vec3<i32>, dims: vec3<u32>, table: u32) -> u32 {
    let d = (p >> vec3<u32>(2u)) - grid_lo;
    if (d.x < 0 || d.y < 0 || d.z < 0) {
        return ABSENT;
    }
    let du = vec3<u32>(d);
    if (du.x >= dims.x || du.y >= dims.y || du.z >= dims.z) {
        return ABSENT;
    }
    let slot = bricks[table + (du.z * dims.y + du.y) * dims.x + du.x];
    if (slot == ABSENT) {
        return ABSENT;
    }
    let l = p & vec3<i32>(3);
    return slot * 64u + u32(l.z * 16 + l.y * 4 + l.x);
}

// voxel_index of p wrapped into a periodic state's period (0: not periodic).
fn voxel_index_wrapped(pos: vec3<i32>, grid_lo: vec3<i32>, dims: vec3<u32>, table: u32,
        period: u32) -> u32 {
    var p = pos;
    if (period != 0u) {
        let n = i32(period);
        p = vec3<i32>(rem_euclid(p.x, n), rem_euclid(p.y, n), rem_euclid(p.z, n));
    }
    return voxel_index(p, grid_lo, dims, table);
}

fn rem_euclid(a: i32, n: i32) -> i32 {
    // Within a period of [0, n) (most calls) without the lane-by-lane divisions (see `resolve`).
    var r = select(a, a + n, a < 0);
    r = select(r, r - n, r >= n);
    if (r >= 0 && r < n) {
        return r;
    }
    return ((a % n) + n) % n;
}

// lowbias32
fn hash32(v: u32) -> u32 {
    var x = v;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// Byte `ch` of the exemplar pixel at coordinate c, stored pixel_words words per pixel from `base`.
fn pixel_byte(base: u32, width: u32, pixel_words: u32, c: u32, ch: u32) -> u32 {
    let word = level[base + (u32(coord_y(c)) * width + u32(coord_x(c))) * pixel_words + ch / 4u];
    return (word >> ((ch % 4u) * 8u)) & 0xFFu;
}

// Word `w` of a voxel's value: channels 4w..4w+3 of the rounded mean of its three pixels.
fn value_word(t: vec3<u32>, w: u32, pixels: vec3<u32>, width: u32, pixel_words: u32, channels: u32) -> u32 {
    var word = 0u;
    for (var b = 0u; b < 4u; b++) {
        let ch = w * 4u + b;
        if (ch < channels) {
            let sum = pixel_byte(pixels.x, width, pixel_words, t.x, ch)
                + pixel_byte(pixels.y, width, pixel_words, t.y, ch)
                + pixel_byte(pixels.z, width, pixel_words, t.z, ch);
            word |= ((sum + 1u) / 3u) << (b * 8u);
        }
    }
    return word;
}
