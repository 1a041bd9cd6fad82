// Evaluation of a gradient solid (tricubic Hermite, zero cross derivatives) at points: an affine
// grid (a volume or a slice of any orientation) or a list. CPU reference, with the derivation:
// src/cpu/tricubic_eval.rs and src/gradient/mod.rs. Results are f32, within a named tolerance of
// the reference (the compiler may fuse multiply-adds).

struct TricubicParams {
    dims_x: u32, dims_y: u32, dims_z: u32, channels: u32,
    mode: u32,
    count: u32, first: u32, grid_stride: u32,
    n_x: u32, n_y: u32,
    origin_x: u32, origin_y: u32, origin_z: u32,
    a_x: u32, a_y: u32, a_z: u32,
    b_x: u32, b_y: u32, b_z: u32,
    c_x: u32, c_y: u32, c_z: u32,
    _pad0: u32, _pad1: u32,
}

const SPACING: f32 = 4.0;
const MAX_CHANNELS: u32 = 16u;

@group(0) @binding(0) var<uniform> params: TricubicParams;
// Per control point (x fastest), per channel: f, df/dx, df/dy, df/dz.
@group(0) @binding(1) var<storage, read> control: array<f32>;
// Mode 1: xyz per point.
@group(0) @binding(2) var<storage, read> points: array<f32>;
@group(0) @binding(3) var<storage, read_write> out_values: array<f32>;

fn vec_of(x: u32, y: u32, z: u32) -> vec3<f32> {
    return vec3<f32>(bitcast<f32>(x), bitcast<f32>(y), bitcast<f32>(z));
}

// Hermite value basis of corner c (0 or 1) at s.
fn hermite_h(c: u32, s: f32) -> f32 {
    if (c == 0u) {
        return 2.0 * s * s * s - 3.0 * s * s + 1.0;
    }
    return 3.0 * s * s - 2.0 * s * s * s;
}

// Hermite derivative basis of corner c at s, scaled to per-voxel gradients.
fn hermite_g(c: u32, s: f32) -> f32 {
    if (c == 0u) {
        return SPACING * (s * s * s - 2.0 * s * s + s);
    }
    return SPACING * (s * s * s - s * s);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tid = gid.x + gid.y * params.grid_stride;
    if (tid >= params.count) {
        return;
    }
    let idx = params.first + tid;
    var x: vec3<f32>;
    if (params.mode == 1u) {
        x = vec3<f32>(points[3u * idx], points[3u * idx + 1u], points[3u * idx + 2u]);
    } else {
        let i = idx % params.n_x;
        let j = (idx / params.n_x) % params.n_y;
        let k = idx / (params.n_x * params.n_y);
        x = vec_of(params.origin_x, params.origin_y, params.origin_z)
            + f32(i) * vec_of(params.a_x, params.a_y, params.a_z)
            + f32(j) * vec_of(params.b_x, params.b_y, params.b_z)
            + f32(k) * vec_of(params.c_x, params.c_y, params.c_z);
    }
    let dims = vec3<u32>(params.dims_x, params.dims_y, params.dims_z);
    var cube: vec3<u32>;
    var t: vec3<f32>;
    for (var a = 0u; a < 3u; a++) {
        let s = clamp(x[a], 0.0, SPACING * f32(dims[a] - 1u)) / SPACING;
        let c = min(u32(floor(s)), dims[a] - 2u);
        cube[a] = c;
        t[a] = s - f32(c);
    }
    var acc: array<f32, MAX_CHANNELS>;
    for (var ch = 0u; ch < MAX_CHANNELS; ch++) {
        acc[ch] = 0.0;
    }
    for (var corner = 0u; corner < 8u; corner++) {
        let c = vec3<u32>(corner & 1u, (corner >> 1u) & 1u, corner >> 2u);
        let p = cube + c;
        let hx = hermite_h(c.x, t.x);
        let hy = hermite_h(c.y, t.y);
        let hz = hermite_h(c.z, t.z);
        let w = vec4<f32>(
            hx * hy * hz,
            hermite_g(c.x, t.x) * hy * hz,
            hx * hermite_g(c.y, t.y) * hz,
            hx * hy * hermite_g(c.z, t.z),
        );
        let base = ((p.z * dims.y + p.y) * dims.x + p.x) * params.channels * 4u;
        for (var ch = 0u; ch < params.channels; ch++) {
            let v = base + ch * 4u;
            acc[ch] += w.x * control[v] + w.y * control[v + 1u] + w.z * control[v + 2u] + w.w * control[v + 3u];
        }
    }
    for (var ch = 0u; ch < params.channels; ch++) {
        out_values[tid * params.channels + ch] = acc[ch];
    }
}
