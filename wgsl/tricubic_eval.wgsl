// Evaluation of a gradient solid (tricubic Hermite, zero cross derivatives) at points: an affine
// grid (a volume or a slice of any orientation) or a list. CPU reference, with the derivation:
// src/cpu/tricubic_eval.rs and src/gradient/mod.rs. Results are f32, within a named tolerance of
// the reference (the compiler may fuse multiply-adds), or with `quantize`, 8-bit values packed
// one point per word (channel c in byte c): a quarter of the output to write and read back,
// which is most of a large volume render's cost on a software device.

struct TricubicParams {
    dims_x: u32, dims_y: u32, dims_z: u32, channels: u32,
    mode: u32,
    count: u32, first: u32, grid_stride: u32,
    n_x: u32, n_y: u32,
    origin_x: u32, origin_y: u32, origin_z: u32,
    a_x: u32, a_y: u32, a_z: u32,
    b_x: u32, b_y: u32, b_z: u32,
    c_x: u32, c_y: u32, c_z: u32,
    quantize: u32, _pad1: u32,
}

const SPACING: f32 = 4.0;
const MAX_CHANNELS: u32 = 16u;

@group(0) @binding(0) var<uniform> params: TricubicParams;
// Per control point (x fastest), per channel: f, df/dx, df/dy, df/dz.
@group(0) @binding(1) var<storage, read> control: array<f32>;
// Mode 1: xyz per point.
@group(0) @binding(2) var<storage, read> points: array<f32>;
// f32 bits per point and channel, or (quantize) one packed word per point.
@group(0) @binding(3) var<storage, read_write> out_values: array<u32>;

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

// Cell mode (a pipeline constant): the volume [0, n)^3 at integer voxels, all of them inside the
// control grid's domain (n <= 4 (dims - 1) + 1 per axis: the last voxel plane lies on the grid's
// far face, in the last cube at fraction 1, as in the general path). An invocation computes the
// 4 x 4 voxels of one z plane of one control cell (4 invocations per cell, 16 cells per
// workgroup). The tricubic is reduced one axis at a time: along z once for the plane (the 4
// corner columns' value and x, y derivative terms), along y once per row, and along x per voxel.
// That is 1/16 of the general path's control-point loads per voxel, which are what it spends
// most of its time on. Same interpolant and fractions; the sums run in another order than the
// general path's, mirrored by the CPU reference (`eval_cells`).
override CELL_MODE: bool = false;

// Control values (f, df/dx, df/dy, df/dz) of channels 0..3 of corner `base` (channels past the
// solid's count read as 0).
struct Corner {
    f: vec4<f32>,
    gx: vec4<f32>,
    gy: vec4<f32>,
    gz: vec4<f32>,
}

fn load_corner(base: u32) -> Corner {
    var k: Corner;
    for (var ch = 0u; ch < 4u; ch++) {
        if (ch < params.channels) {
            let v = base + ch * 4u;
            k.f[ch] = control[v];
            k.gx[ch] = control[v + 1u];
            k.gy[ch] = control[v + 2u];
            k.gz[ch] = control[v + 3u];
        }
    }
    return k;
}

// A corner column (fixed x, y corner) reduced along z at the plane's fraction: the value and
// the x and y derivative terms there.
struct Column {
    f: vec4<f32>,
    gx: vec4<f32>,
    gy: vec4<f32>,
}

fn column(base: u32, z_step: u32, tz: f32) -> Column {
    let k0 = load_corner(base);
    let k1 = load_corner(base + z_step);
    let h0 = hermite_h(0u, tz);
    let h1 = hermite_h(1u, tz);
    var c: Column;
    c.f = k0.f * h0 + k1.f * h1 + k0.gz * hermite_g(0u, tz) + k1.gz * hermite_g(1u, tz);
    c.gx = k0.gx * h0 + k1.gx * h1;
    c.gy = k0.gy * h0 + k1.gy * h1;
    return c;
}

fn main_cells(workgroup: vec3<u32>, local: u32) {
    // Cells of this dispatch: whole z layers of cells, from the one holding point `first`.
    let cells_x = (params.n_x + 3u) / 4u;
    let cells_y = (params.n_y + 3u) / 4u;
    let cell = (workgroup.x + workgroup.y * (params.grid_stride / 64u)) * 16u + (local >> 2u);
    let z0 = params.first / (params.n_x * params.n_y);
    var cube = vec3<u32>(cell % cells_x, (cell / cells_x) % cells_y, z0 / 4u + cell / (cells_x * cells_y));
    let lz = local & 3u;
    let corner_voxel = 4u * cube + vec3<u32>(0u, 0u, lz);
    if (corner_voxel.y >= params.n_y || corner_voxel.z * params.n_x * params.n_y >= params.first + params.count) {
        return;
    }
    let dims = vec3<u32>(params.dims_x, params.dims_y, params.dims_z);
    // A cell on the far face (index dims - 1) is the last cube at fraction 1.
    let unclamped = cube;
    cube = min(cube, dims - 2u);
    let shift = vec3<f32>(unclamped - cube);
    let tz = f32(lz) / SPACING + shift.z;
    let stride = params.channels * 4u;
    let base = ((cube.z * dims.y + cube.y) * dims.x + cube.x) * stride;
    let z_step = dims.x * dims.y * stride;
    let y_step = dims.x * stride;
    // Columns (x corner, y corner).
    let c00 = column(base, z_step, tz);
    let c10 = column(base + stride, z_step, tz);
    let c01 = column(base + y_step, z_step, tz);
    let c11 = column(base + y_step + stride, z_step, tz);
    for (var ly = 0u; ly < 4u; ly++) {
        let y = corner_voxel.y + ly;
        if (y >= params.n_y) {
            break;
        }
        let ty = f32(ly) / SPACING + shift.y;
        let hy0 = hermite_h(0u, ty);
        let hy1 = hermite_h(1u, ty);
        let gy0 = hermite_g(0u, ty);
        let gy1 = hermite_g(1u, ty);
        // Along x: value = a0 H0(t) + a1 H1(t) + b0 G0(t) + b1 G1(t), per channel.
        let a0 = c00.f * hy0 + c01.f * hy1 + c00.gy * gy0 + c01.gy * gy1;
        let a1 = c10.f * hy0 + c11.f * hy1 + c10.gy * gy0 + c11.gy * gy1;
        let b0 = c00.gx * hy0 + c01.gx * hy1;
        let b1 = c10.gx * hy0 + c11.gx * hy1;
        let row_first = (corner_voxel.z * params.n_y + y) * params.n_x + corner_voxel.x;
        for (var lx = 0u; lx < 4u; lx++) {
            let idx = row_first + lx;
            if (corner_voxel.x + lx >= params.n_x || idx < params.first || idx - params.first >= params.count) {
                continue;
            }
            let t = f32(lx) / SPACING + shift.x;
            let acc = a0 * hermite_h(0u, t) + a1 * hermite_h(1u, t) + b0 * hermite_g(0u, t)
                + b1 * hermite_g(1u, t);
            let tid = idx - params.first;
            if (params.quantize == 1u) {
                // Channels past the solid's count are 0 and quantize to 0.
                let b = vec4<u32>(clamp(floor(acc + 0.5), vec4<f32>(0.0), vec4<f32>(255.0)));
                out_values[tid] = b.x | (b.y << 8u) | (b.z << 16u) | (b.w << 24u);
            } else {
                for (var ch = 0u; ch < params.channels; ch++) {
                    out_values[tid * params.channels + ch] = bitcast<u32>(acc[ch]);
                }
            }
        }
    }
}

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(workgroup_id) workgroup: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    if (CELL_MODE) {
        main_cells(workgroup, local);
        return;
    }
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
    if (params.quantize == 1u) {
        // Round half up, then clamp: for these values the same as the host's f32::round
        // (half away from zero) followed by the clamp. WGSL's round() would round half to even.
        var word = 0u;
        for (var ch = 0u; ch < params.channels; ch++) {
            word |= u32(clamp(floor(acc[ch] + 0.5), 0.0, 255.0)) << (8u * ch);
        }
        out_values[tid] = word;
        return;
    }
    for (var ch = 0u; ch < params.channels; ch++) {
        out_values[tid * params.channels + ch] = bitcast<u32>(acc[ch]);
    }
}
