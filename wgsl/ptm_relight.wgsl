// A polynomial texture map rendered under one light: per pixel, decode the texel's quantized
// coefficients ((q - bias) * scale / 255), evaluate the biquadratic at (lu, lv), colour it (LRGB:
// luminance times the stored colour; RGB: one polynomial per channel), and optionally add a
// Blinn-Phong highlight around the normal that maximizes the luminance polynomial. CPU reference,
// same order of operations: src/cpu/ptm_relight.rs. Results are f32 within a named tolerance of
// the reference (the compiler may fuse multiply-adds; inverseSqrt and division are not correctly
// rounded).

struct PtmRelightParams {
    width: u32, count: u32, first: u32, grid_stride: u32,
    // 0: PTM_FORMAT_RGB (18 bytes a texel), 1: PTM_FORMAT_LRGB (9 bytes a texel).
    format: u32, texel_bytes: u32,
    // f32 bits: light (lu, lv, lw) with lw = sqrt(1 - lu^2 - lv^2), specular strength.
    light_u: u32, light_v: u32, light_w: u32, specular: u32,
    // f32 bits / i32 bits, per coefficient index.
    scale0: u32, scale1: u32, scale2: u32, scale3: u32, scale4: u32, scale5: u32,
    bias0: u32, bias1: u32, bias2: u32, bias3: u32, bias4: u32, bias5: u32,
    _pad0: u32, _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: PtmRelightParams;
// The texels of this dispatch's pixels, 4 bytes a word, little-endian.
@group(0) @binding(1) var<storage, read> texels: array<u32>;
// r, g, b per pixel, unit intensity.
@group(0) @binding(2) var<storage, read_write> out_rgb: array<f32>;

fn byte_at(k: u32) -> u32 {
    return (texels[k >> 2u] >> (8u * (k & 3u))) & 0xFFu;
}

fn scale_of(i: u32) -> f32 {
    switch i {
        case 0u: { return bitcast<f32>(params.scale0); }
        case 1u: { return bitcast<f32>(params.scale1); }
        case 2u: { return bitcast<f32>(params.scale2); }
        case 3u: { return bitcast<f32>(params.scale3); }
        case 4u: { return bitcast<f32>(params.scale4); }
        default: { return bitcast<f32>(params.scale5); }
    }
}

fn bias_of(i: u32) -> i32 {
    switch i {
        case 0u: { return bitcast<i32>(params.bias0); }
        case 1u: { return bitcast<i32>(params.bias1); }
        case 2u: { return bitcast<i32>(params.bias2); }
        case 3u: { return bitcast<i32>(params.bias3); }
        case 4u: { return bitcast<i32>(params.bias4); }
        default: { return bitcast<i32>(params.bias5); }
    }
}

// The 6 coefficients of plane p of the texel starting at byte `base`.
fn decode(base: u32, p: u32) -> array<f32, 6> {
    var a: array<f32, 6>;
    for (var i = 0u; i < 6u; i++) {
        let q = i32(byte_at(base + p * 6u + i));
        a[i] = f32(q - bias_of(i)) * scale_of(i) / 255.0;
    }
    return a;
}

fn poly(a: array<f32, 6>, lu: f32, lv: f32) -> f32 {
    return a[0] * lu * lu + a[1] * lv * lv + a[2] * lu * lv + a[3] * lu + a[4] * lv + a[5];
}

// The surface normal of a luminance polynomial: the light direction maximizing it (Malzbender
// et al. 2001), from the stationary point of the quadratic when it is a maximum, else from the
// linear term over the constant (what a Lambertian fit gives); clamped to the unit disk.
fn normal_of(a: array<f32, 6>) -> vec3<f32> {
    var u = 0.0;
    var v = 0.0;
    let det = 4.0 * a[0] * a[1] - a[2] * a[2];
    if (a[0] < 0.0 && det > 0.0) {
        u = (a[2] * a[4] - 2.0 * a[1] * a[3]) / det;
        v = (a[2] * a[3] - 2.0 * a[0] * a[4]) / det;
    } else if (a[5] > 1e-6) {
        u = a[3] / a[5];
        v = a[4] / a[5];
    }
    let r2 = u * u + v * v;
    if (r2 > 1.0) {
        let k = 1.0 / sqrt(r2);
        u = u * k;
        v = v * k;
    }
    return vec3<f32>(u, v, sqrt(max(0.0, 1.0 - u * u - v * v)));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tid = gid.x + gid.y * params.grid_stride;
    if (tid >= params.count) {
        return;
    }
    let base = tid * params.texel_bytes;
    let lu = bitcast<f32>(params.light_u);
    let lv = bitcast<f32>(params.light_v);
    var rgb: vec3<f32>;
    var lum: array<f32, 6>;
    if (params.format == 1u) {
        lum = decode(base, 0u);
        let l = poly(lum, lu, lv);
        rgb = vec3<f32>(
            l * (f32(byte_at(base + 6u)) / 255.0),
            l * (f32(byte_at(base + 7u)) / 255.0),
            l * (f32(byte_at(base + 8u)) / 255.0),
        );
    } else {
        let r = decode(base, 0u);
        let g = decode(base, 1u);
        let b = decode(base, 2u);
        rgb = vec3<f32>(poly(r, lu, lv), poly(g, lu, lv), poly(b, lu, lv));
        for (var i = 0u; i < 6u; i++) {
            lum[i] = (r[i] + g[i] + b[i]) / 3.0;
        }
    }
    let k = bitcast<f32>(params.specular);
    if (k > 0.0) {
        let n = normal_of(lum);
        let h0 = vec3<f32>(lu, lv, bitcast<f32>(params.light_w) + 1.0);
        let h = h0 / sqrt(dot(h0, h0));
        // max(n.h, 0)^32 by five squarings.
        var s = max(dot(n, h), 0.0);
        s = s * s;
        s = s * s;
        s = s * s;
        s = s * s;
        s = s * s;
        rgb = rgb + vec3<f32>(k * s);
    }
    out_rgb[3u * tid] = rgb.x;
    out_rgb[3u * tid + 1u] = rgb.y;
    out_rgb[3u * tid + 2u] = rgb.z;
}
