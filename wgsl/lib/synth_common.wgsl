// Helpers shared by the synthesis kernels (prepended to init, upsample, correct and colorize by
// src/gpu/shaders.rs). CPU counterparts: src/cpu/synth_common.rs, src/util/hash.rs.
//
// Every synthesis kernel binds the level's packed exemplar data at @binding(1) (kernels that do
// not use it leave it out of their layout). A state holds per voxel its triple (3 words), then
// its value, the mean of its three exemplar pixels (pixel_words words): stride 3 + pixel_words.

@group(0) @binding(1) var<storage, read> level: array<u32>;

// Border::resolve: 0 = wrap, 1 = mirror (reflect-101).
fn resolve(c: i32, len: u32, border: u32) -> u32 {
    let n = i32(len);
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

fn box_index(p: vec3<i32>, lo: vec3<i32>, size: vec3<u32>) -> u32 {
    let d = vec3<u32>(p - lo);
    return (d.z * size.y + d.y) * size.x + d.x;
}

fn rem_euclid(a: i32, n: i32) -> i32 {
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
