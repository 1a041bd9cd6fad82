// One correction sub-pass over the voxels of one parity class in a box (paper 5.1, two-step
// search with 3D candidates; or independent 2D candidates, mode 1). CPU reference, with the
// description of each step: src/cpu/correct.rs.

struct CorrectParams {
    grid_lo_x: i32, grid_lo_y: i32, grid_lo_z: i32,
    grid_x: u32, grid_y: u32, grid_z: u32,
    table_offset: u32,
    list_offset: u32, list_count: u32,
    class_x: u32, class_y: u32, class_z: u32,
    ex_width: u32, ex_height: u32, channels: u32, pixel_words: u32,
    pca_in: u32, pca_out: u32, shift: u32, proj_words: u32,
    k2d: u32, k3d_used: u32, k3d_stride: u32, border: u32,
    mode: u32,
    shared_sets: u32,
    pixels0: u32, pixels1: u32, pixels2: u32,
    proj0: u32, proj1: u32, proj2: u32,
    mean0: u32, mean1: u32, mean2: u32,
    weights0: u32, weights1: u32, weights2: u32,
    cand2d0: u32, cand2d1: u32, cand2d2: u32,
    cand3d0: u32, cand3d1: u32, cand3d2: u32,
    counts0: u32, counts1: u32, counts2: u32,
    grid_stride: u32, mask_offset: u32, period: u32, _pad3: u32, _pad4: u32,
}

const MAX_PCA_OUT: u32 = 16u;
// Pipeline-overridable copies of params.channels, params.pca_out and params.k2d (the host sets
// them equal): constant loop bounds let the driver unroll the hot loops and keep the
// accumulators in registers. The kernel checks they agree with the uniforms.
override CHANNELS: u32 = 3u;
override PCA_OUT: u32 = 8u;
override K2D: u32 = 2u;

@group(0) @binding(0) var<uniform> params: CorrectParams;
// (binding 1: level data, declared by the prelude)
@group(0) @binding(2) var<storage, read> state: array<u32>;
@group(0) @binding(3) var<storage, read_write> next_state: array<u32>;
// (binding 4: the level's brick index, declared by the prelude)

// Index of voxel p in the state (ABSENT when its brick is not stored).
fn state_index(pos: vec3<i32>) -> u32 {
    var p = pos;
    if (params.period != 0u) {
        let n = i32(params.period);
        p = vec3<i32>(rem_euclid(p.x, n), rem_euclid(p.y, n), rem_euclid(p.z, n));
    }
    return voxel_index(p, vec3<i32>(params.grid_lo_x, params.grid_lo_y, params.grid_lo_z),
        vec3<u32>(params.grid_x, params.grid_y, params.grid_z), params.table_offset);
}

fn stride() -> u32 {
    return 3u + params.pixel_words;
}

// Voxels outside the stored bricks read as zero (only voxels the plan does not need read them).
fn triple(p: vec3<i32>) -> vec3<u32> {
    let s = state_index(p);
    if (s == ABSENT) {
        return vec3<u32>(0u);
    }
    let i = s * stride();
    return vec3<u32>(state[i], state[i + 1u], state[i + 2u]);
}

// Unit vector along volume axis `a`.
fn axis(a: u32) -> vec3<i32> {
    return vec3<i32>(select(0, 1, a == 0u), select(0, 1, a == 1u), select(0, 1, a == 2u));
}

fn project_plane(pos: vec3<i32>, a: u32) -> array<i32, MAX_PCA_OUT> {
    let eu = axis((a + 1u) % 3u);
    let ev = axis((a + 2u) % 3u);
    let mean = select(select(params.mean2, params.mean1, a == 1u), params.mean0, a == 0u);
    let weights = select(select(params.weights2, params.weights1, a == 1u), params.weights0, a == 0u);
    var acc: array<i32, MAX_PCA_OUT>;
    for (var j = 0u; j < MAX_PCA_OUT; j++) {
        acc[j] = 0;
    }
    var i = 0u;
    for (var dv = -2; dv <= 2; dv++) {
        for (var du = -2; du <= 2; du++) {
            // One brick lookup per neighbour; absent voxels read as zero.
            let s = state_index(pos + du * eu + dv * ev);
            // The neighbour's first value word, read once for its (up to 4) channels.
            var word = 0u;
            if (s != ABSENT) {
                word = state[s * stride() + 3u];
            }
            for (var ch = 0u; ch < CHANNELS; ch++) {
                var byte = 0u;
                if (ch >= 4u && s != ABSENT) {
                    byte = (state[s * stride() + 3u + ch / 4u] >> ((ch % 4u) * 8u)) & 0xFFu;
                } else if (ch < 4u) {
                    byte = (word >> (ch * 8u)) & 0xFFu;
                }
                let centred = i32(byte) - bitcast<i32>(level[mean + i]);
                for (var j = 0u; j < PCA_OUT; j++) {
                    acc[j] += centred * bitcast<i32>(level[weights + j * params.pca_in + i]);
                }
                i++;
            }
        }
    }
    let round = 1 << (params.shift - 1u);
    var q: array<i32, MAX_PCA_OUT>;
    for (var j = 0u; j < MAX_PCA_OUT; j++) {
        q[j] = 0;
    }
    for (var j = 0u; j < PCA_OUT; j++) {
        q[j] = clamp(((acc[j] + round) >> params.shift) + 128, 0, 255);
    }
    return q;
}

fn distance(q: ptr<function, array<i32, MAX_PCA_OUT>>, a: u32, c: u32) -> u32 {
    let proj = select(select(params.proj2, params.proj1, a == 1u), params.proj0, a == 0u);
    let base = proj + (u32(coord_y(c)) * params.ex_width + u32(coord_x(c))) * params.proj_words;
    var d = 0u;
    for (var j = 0u; j < PCA_OUT; j++) {
        let byte = (level[base + j / 4u] >> ((j % 4u) * 8u)) & 0xFFu;
        let diff = (*q)[j] - i32(byte);
        d += u32(diff * diff);
    }
    return d;
}

// Usage penalty of pixel c of E_a in sixteenths (analysis::balance): one word per pixel right
// after E_a's pixels in the level data (lazy::pack).
fn penalty(a: u32, c: u32) -> u32 {
    let pixels = select(select(params.pixels2, params.pixels1, a == 1u), params.pixels0, a == 0u);
    let table = pixels + params.ex_width * params.ex_height * params.pixel_words;
    return level[table + u32(coord_y(c)) * params.ex_width + u32(coord_x(c))];
}

// The scale of a triple's distance: 16 + the penalties of its three pixels (the scaled
// distance stays below 2^32: at most 3 x 12 x 255^2 x (16 + 3 x 255)).
fn factor(t: vec3<u32>) -> u32 {
    return 16u + penalty(0u, t.x) + penalty(1u, t.y) + penalty(2u, t.z);
}

fn best_2d(pos: vec3<i32>, a: u32, q: ptr<function, array<i32, MAX_PCA_OUT>>) -> u32 {
    let eu = axis((a + 1u) % 3u);
    let ev = axis((a + 2u) % 3u);
    let cand2d = select(select(params.cand2d2, params.cand2d1, a == 1u), params.cand2d0, a == 0u);
    var best = 0u;
    var best_d = 0xFFFFFFFFu;
    for (var dv = -1; dv <= 1; dv++) {
        for (var du = -1; du <= 1; du++) {
            let c = triple(pos + du * eu + dv * ev)[a];
            let sx = coord_x(c) - du;
            let sy = coord_y(c) - dv;
            if (params.border != 0u && (sx < 0 || sy < 0 || sx >= i32(params.ex_width) || sy >= i32(params.ex_height))) {
                continue;
            }
            let src = pack_resolved(sx, sy, params.ex_width, params.ex_height, params.border);
            let list = cand2d + (u32(coord_y(src)) * params.ex_width + u32(coord_x(src))) * params.k2d;
            for (var j = 0u; j < K2D; j++) {
                let cand = level[list + j];
                let d = distance(q, a, cand) * (16u + penalty(a, cand));
                if (d < best_d) {
                    best_d = d;
                    best = cand;
                }
            }
        }
    }
    return best;
}

// rotate_from_shared of src/analysis/frame.rs.
fn rotate(t: vec3<u32>, a: u32) -> vec3<u32> {
    if (a == 1u) {
        return vec3<u32>(t.z, t.x, t.y);
    }
    if (a == 2u) {
        return vec3<u32>(t.y, t.z, t.x);
    }
    return t;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tid = gid.x + gid.y * params.grid_stride;
    if (tid >= params.list_count * 8u) {
        return;
    }
    if (CHANNELS != params.channels || PCA_OUT != params.pca_out || K2D != params.k2d) {
        return; // a pipeline built for other constants: leave the voxel unwritten (sentinel shows)
    }
    let k = tid % 8u;
    let b = tid / 8u;
    if (((bricks[params.mask_offset + b / 4u] >> ((b % 4u) * 8u + k)) & 1u) == 0u) {
        return; // a voxel the plan does not need
    }
    let cls = vec3<u32>(params.class_x, params.class_y, params.class_z);
    let pos = brick_at(params.list_offset, tid / 8u) * 4
        + vec3<i32>(cls + 2u * vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u));
    var q0 = project_plane(pos, 0u);
    var q1 = project_plane(pos, 1u);
    var q2 = project_plane(pos, 2u);
    let best2d = vec3<u32>(best_2d(pos, 0u, &q0), best_2d(pos, 1u, &q1), best_2d(pos, 2u, &q2));
    var best = best2d;
    if (params.mode == 0u) {
        best = triple(pos);
        var best_d = (distance(&q0, 0u, best.x) + distance(&q1, 1u, best.y) + distance(&q2, 2u, best.z)) * factor(best);
        for (var a = 0u; a < 3u; a++) {
            var owner = a;
            if (params.shared_sets != 0u) {
                owner = 0u;
            }
            // Every 3D candidate of pixel best2d[a] has it as its a coordinate (the .ssa reader
            // checks it): its distance on plane a is scored once.
            var own = 0u;
            if (a == 0u) {
                own = distance(&q0, 0u, best2d.x);
            } else if (a == 1u) {
                own = distance(&q1, 1u, best2d.y);
            } else {
                own = distance(&q2, 2u, best2d.z);
            }
            let pixel = u32(coord_y(best2d[a])) * params.ex_width + u32(coord_x(best2d[a]));
            let counts = select(select(params.counts2, params.counts1, owner == 1u), params.counts0, owner == 0u);
            let cand3d = select(select(params.cand3d2, params.cand3d1, owner == 1u), params.cand3d0, owner == 0u);
            let count = min(level[counts + pixel], params.k3d_used);
            let list = cand3d + pixel * params.k3d_stride * 3u;
            for (var j = 0u; j < count; j++) {
                let e = list + j * 3u;
                var t = vec3<u32>(level[e], level[e + 1u], level[e + 2u]);
                if (params.shared_sets != 0u) {
                    t = rotate(t, a);
                }
                var d = own;
                if (a != 0u) {
                    d += distance(&q0, 0u, t.x);
                }
                if (a != 1u) {
                    d += distance(&q1, 1u, t.y);
                }
                if (a != 2u) {
                    d += distance(&q2, 2u, t.z);
                }
                d *= factor(t);
                if (d < best_d) {
                    best_d = d;
                    best = t;
                }
            }
        }
    }
    let i = state_index(pos) * stride(); // active bricks are stored
    next_state[i] = best.x;
    next_state[i + 1u] = best.y;
    next_state[i + 2u] = best.z;
    let pixels = vec3<u32>(params.pixels0, params.pixels1, params.pixels2);
    for (var wd = 0u; wd < params.pixel_words; wd++) {
        next_state[i + 3u + wd] = value_word(best, wd, pixels, params.ex_width, params.pixel_words, params.channels);
    }
}
