// Projection of exemplar neighbourhoods onto their PCA basis with 8-bit quantization.
// CPU reference: src/cpu/project.rs (same loops, same integer arithmetic).
//
// One invocation per pixel of the chunk [first_pixel, first_pixel + pixel_count):
//   gather the 5x5 neighbourhood (rows outermost, then columns, then channels), subtract the
//   integer mean, accumulate against the fixed-point weights in i32, round-shift, offset by 128,
//   clamp to 0..255, and pack four bytes per u32 (byte j of the vector in bits 8*(j%4)).

struct ProjectParams {
    width: u32,
    height: u32,
    channels: u32,
    border: u32,
    input_dims: u32,
    output_dims: u32,
    shift: u32,
    first_pixel: u32,
    pixel_count: u32,
    words_per_vector: u32,
    grid_stride: u32,
    _pad: u32,
}

const HALF: i32 = 2;
const MAX_OUTPUT_DIMS: u32 = 16u;

@group(0) @binding(0) var<uniform> params: ProjectParams;
// Image bytes, pixel-major, channels interleaved, four bytes per word (little-endian).
@group(0) @binding(1) var<storage, read> image: array<u32>;
@group(0) @binding(2) var<storage, read> mean: array<i32>;
// output_dims x input_dims, row-major.
@group(0) @binding(3) var<storage, read> weights: array<i32>;
@group(0) @binding(4) var<storage, read_write> projected: array<u32>;

// Border::resolve: 0 = wrap, 1 = mirror (reflect-101).
fn resolve(c: i32, len: u32) -> u32 {
    let n = i32(len);
    if (params.border == 0u) {
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

fn image_byte(index: u32) -> i32 {
    return i32((image[index >> 2u] >> ((index & 3u) * 8u)) & 0xFFu);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let local = gid.x + gid.y * params.grid_stride;
    if (local >= params.pixel_count) {
        return;
    }
    let pixel = params.first_pixel + local;
    let px = i32(pixel % params.width);
    let py = i32(pixel / params.width);

    var acc: array<i32, MAX_OUTPUT_DIMS>;
    for (var j = 0u; j < MAX_OUTPUT_DIMS; j++) {
        acc[j] = 0;
    }
    var i = 0u;
    for (var dv = -HALF; dv <= HALF; dv++) {
        let sy = resolve(py + dv, params.height);
        for (var du = -HALF; du <= HALF; du++) {
            let sx = resolve(px + du, params.width);
            let base = (sy * params.width + sx) * params.channels;
            for (var ch = 0u; ch < params.channels; ch++) {
                let centred = image_byte(base + ch) - mean[i];
                for (var j = 0u; j < params.output_dims; j++) {
                    acc[j] += centred * weights[j * params.input_dims + i];
                }
                i++;
            }
        }
    }

    let round = 1 << (params.shift - 1u);
    let out_base = local * params.words_per_vector;
    for (var w = 0u; w < params.words_per_vector; w++) {
        var word = 0u;
        for (var b = 0u; b < 4u; b++) {
            let j = w * 4u + b;
            if (j < params.output_dims) {
                let q = clamp(((acc[j] + round) >> params.shift) + 128, 0, 255);
                word |= u32(q) << (b * 8u);
            }
        }
        projected[out_base + w] = word;
    }
}
