// Voxel colours of an output box, colour channels packed into one u32. Each channel c comes from
// the source in bits 4c..4c+3 of params.source: 0 the voxel's cached value (the rounded mean of
// its three exemplar pixels), a + 1 the pixel of exemplar a at the voxel's coordinate in it, 4 the
// cached value mapped through the `--color matched` table (src/lazy/color_match.rs), 5 the fitted
// weighting of the three pixels (`fitted` below).
// CPU reference: src/cpu/colorize.rs.

struct ColorizeParams {
    ex: ExemplarFields,
    grid_lo_x: i32, grid_lo_y: i32, grid_lo_z: i32,
    grid_x: u32, grid_y: u32, grid_z: u32,
    table_offset: u32,
    list_offset: u32, list_count: u32, grid_stride: u32,
    match_table: u32, color_channels: u32, source: u32,
    period: u32, _r1: u32, _r2: u32,
}

@group(0) @binding(0) var<uniform> params: ColorizeParams;
// (binding 1: level data, declared by the prelude)
@group(0) @binding(2) var<storage, read> state: array<u32>;
@group(0) @binding(3) var<storage, read_write> colors: array<u32>;
// (binding 4: the level's brick index, declared by the prelude)

// contract::uniforms::FITTED_REACH.
const FITTED_REACH: i32 = 2;

// Index of voxel p in the state (wrapped into a tileable solid's period); ABSENT when its brick
// is not stored.
fn state_slot(pos: vec3<i32>) -> u32 {
    return voxel_index_wrapped(pos, vec3<i32>(params.grid_lo_x, params.grid_lo_y, params.grid_lo_z),
        vec3<u32>(params.grid_x, params.grid_y, params.grid_z), params.table_offset, params.period);
}

// Word 0 of exemplar a's pixel at (x, y), resolved against its border.
fn exemplar_word(a: u32, x: i32, y: i32) -> u32 {
    let pixels = array<u32, 3>(params.ex.pixels0, params.ex.pixels1, params.ex.pixels2);
    let rx = resolve(x, params.ex.width, params.ex.border);
    let ry = resolve(y, params.ex.height, params.ex.border);
    return level[pixels[a] + (ry * params.ex.width + rx) * params.ex.pixel_words];
}

fn color_distance(a: u32, b: u32) -> u32 {
    var d = 0u;
    for (var c = 0u; c < min(params.color_channels, 4u); c++) {
        let e = i32((a >> (8u * c)) & 0xFFu) - i32((b >> (8u * c)) & 0xFFu);
        d += u32(e * e);
    }
    return d;
}

// The voxel's three exemplar pixels weighted by how well each plane's 5x5 neighbourhood of mean
// colours fits exemplar a's window around the pixel (integer weights; see the CPU reference).
fn fitted(pos: vec3<i32>, i: u32) -> u32 {
    let stride = 3u + params.ex.pixel_words;
    var misfit = array<u32, 3>(0u, 0u, 0u);
    var pixels = array<u32, 3>(0u, 0u, 0u);
    for (var a = 0u; a < 3u; a++) {
        let ua = (a + 1u) % 3u;
        let va = (a + 2u) % 3u;
        let t = state[i + a];
        let x = coord_x(t);
        let y = coord_y(t);
        pixels[a] = exemplar_word(a, x, y);
        for (var dv = -FITTED_REACH; dv <= FITTED_REACH; dv++) {
            for (var du = -FITTED_REACH; du <= FITTED_REACH; du++) {
                var n = pos;
                n[ua] += du;
                n[va] += dv;
                let s = state_slot(n);
                var mean = 0u;
                if (s != ABSENT) {
                    mean = state[s * stride + 3u];
                }
                misfit[a] += color_distance(mean, exemplar_word(a, x + du, y + dv));
            }
        }
    }
    let best = min(misfit[0], min(misfit[1], misfit[2]));
    var weights = array<u32, 3>(0u, 0u, 0u);
    var total = 0u;
    for (var a = 0u; a < 3u; a++) {
        let q = ((best + 1u) << 8u) / (misfit[a] + 1u);
        weights[a] = q * q;
        total += weights[a];
    }
    var out = 0u;
    for (var c = 0u; c < min(params.color_channels, 4u); c++) {
        var sum = 0u;
        for (var a = 0u; a < 3u; a++) {
            sum += weights[a] * ((pixels[a] >> (8u * c)) & 0xFFu);
        }
        out |= ((sum + total / 2u) / total) << (8u * c);
    }
    return out;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tid = gid.x + gid.y * params.grid_stride;
    if (tid >= params.list_count * 64u) {
        return;
    }
    let pos = voxel_of(brick_at(params.list_offset, tid / 64u), tid % 64u);
    let slot = state_slot(pos);
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
    var fitted_word = 0u;
    for (var c = 0u; c < 4u; c++) {
        if (((params.source >> (c * 4u)) & 0xFu) == 5u) {
            fitted_word = fitted(pos, i);
            break;
        }
    }
    var word = 0u;
    for (var c = 0u; c < 4u; c++) {
        let code = (params.source >> (c * 4u)) & 0xFu;
        var picked = value;
        if (code == 4u) {
            // Byte c of table word k: channel c's output for value k.
            picked = level[params.match_table + ((value >> (c * 8u)) & 0xFFu)];
        } else if (code == 5u) {
            picked = fitted_word;
        } else if (code != 0u) {
            picked = exemplar_word(code - 1u, coord_x(state[i + code - 1u]), coord_y(state[i + code - 1u]));
        }
        word |= picked & (0xFFu << (c * 8u));
    }
    colors[tid] = word & mask;
}
