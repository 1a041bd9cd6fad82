// A polynomial texture map rendered under one light: per pixel, decode the texel's quantized
// coefficients ((q - bias) * step, step = scale / 255), evaluate the biquadratic at (lu, lv), colour it (LRGB:
// luminance times the stored colour; RGB: one polynomial per channel), and optionally add a
// Blinn-Phong highlight around the normal that maximizes the luminance polynomial. CPU reference,
// same order of operations: src/cpu/ptm_relight.rs. Results are f32 within a named tolerance of
// the reference (the compiler may fuse multiply-adds; inverseSqrt and division are not correctly
// rounded).

struct PtmRelightParams {
    width: u32, count: u32, first: u32, grid_stride: u32,
    // 0: PTM_FORMAT_RGB (18 bytes in 5 words a texel), 1: PTM_FORMAT_LRGB (9 bytes in 3 words).
    format: u32, texel_words: u32,
    // f32 bits: light (lu, lv, lw) with lw = sqrt(1 - lu^2 - lv^2), specular strength.
    light_u: u32, light_v: u32, light_w: u32, specular: u32,
    // f32 bits / i32 bits, per coefficient index.
    step0: u32, step1: u32, step2: u32, step3: u32, step4: u32, step5: u32,
    bias0: u32, bias1: u32, bias2: u32, bias3: u32, bias4: u32, bias5: u32,
    _pad0: u32, _pad1: u32,
}

// 1/255 rounded to f32 (the CPU reference multiplies by the same constant).
const INV_255: f32 = 0.003921569;

@group(0) @binding(0) var<uniform> params: PtmRelightParams;
// The texels of this dispatch's pixels, each padded to whole words, 4 bytes a word,
// little-endian.
@group(0) @binding(1) var<storage, read> texels: array<u32>;
// r, g, b per pixel, unit intensity.
@group(0) @binding(2) var<storage, read_write> out_rgb: array<f32>;

// Byte k of the texel whose first word is `base` (k is a constant at every call site).
fn byte_at(base: u32, k: u32) -> u32 {
    return (texels[base + (k >> 2u)] >> (8u * (k & 3u))) & 0xFFu;
}

fn coeff(base: u32, k: u32, bias: u32, step: u32) -> f32 {
    return f32(i32(byte_at(base, k)) - bitcast<i32>(bias)) * bitcast<f32>(step);
}

// The 6 coefficients of plane p of the texel starting at word `base`.
fn decode(base: u32, p: u32) -> array<f32, 6> {
    let k = 6u * p;
    return array<f32, 6>(
        coeff(base, k, params.bias0, params.step0),
        coeff(base, k + 1u, params.bias1, params.step1),
        coeff(base, k + 2u, params.bias2, params.step2),
        coeff(base, k + 3u, params.bias3, params.step3),
        coeff(base, k + 4u, params.bias4, params.step4),
        coeff(base, k + 5u, params.bias5, params.step5),
    );
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
    let base = tid * params.texel_words;
    let lu = bitcast<f32>(params.light_u);
    let lv = bitcast<f32>(params.light_v);
    var rgb: vec3<f32>;
    var lum: array<f32, 6>;
    if (params.format == 1u) {
        lum = decode(base, 0u);
        let l = poly(lum, lu, lv);
        rgb = vec3<f32>(
            l * (f32(byte_at(base, 6u)) * INV_255),
            l * (f32(byte_at(base, 7u)) * INV_255),
            l * (f32(byte_at(base, 8u)) * INV_255),
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
