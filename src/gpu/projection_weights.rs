//! `correct`'s projection weights as its uniform buffer holds them (`ProjectionWeights` in
//! wgsl/correct.wgsl): the biases, then the weights in one of three layouts.

use crate::contract::level::LevelPack;

/// Vectors (`vec4<i32>`) of `ProjectionWeights` in wgsl/correct.wgsl, and where its weights
/// start (after 4 bias vectors per plane).
pub const PROJECTION_VECTORS: usize = 4096;
const PROJECTION_BASE: usize = 12;

/// Neighbours of a plane's neighbourhood (5 x 5), each contributing `channels` inputs in a row
/// to the PCA projection.
const PLANE_NEIGHBOURS: usize = 25;

/// How the projection uniform holds the weights (the kernel's `WEIGHT_LAYOUT`; its comment on
/// `ProjectionWeights` describes each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightLayout {
    /// One 32-bit weight per output: the only layout for weights beyond 16 bits.
    Plain,
    /// 16-bit weights two to a word: the default.
    Halves,
    /// 16-bit weights as high and low bytes, for packed byte dot products
    /// ([`GpuOptions::byte_weights`](crate::gpu::GpuOptions::byte_weights)).
    Bytes,
}

impl WeightLayout {
    /// The kernel's `WEIGHT_LAYOUT` value.
    pub(super) fn constant(self) -> f64 {
        match self {
            WeightLayout::Plain => 0.0,
            WeightLayout::Halves => 1.0,
            WeightLayout::Bytes => 2.0,
        }
    }
}

/// Level `p`'s PCA projection laid out as wgsl/correct.wgsl's `ProjectionWeights` reads it: per
/// plane a, the biases b_j = sum_i mean_i * w_ji (wrapping, as the kernel's partial sums) in 4
/// vectors at 4a, then from PROJECTION_BASE the weights in `preferred` layout where every weight
/// fits 16 bits (and, for bytes, the inputs are the 25 neighbours' channels), else plain:
/// - Plain: per plane and input i, vector g holds outputs 4g..4g+3.
/// - Halves: per plane and input i, vector h holds outputs 8h..8h+3 in its low halves and
///   8h+4..8h+7 in its high halves.
/// - Bytes: per plane, neighbour and pixel word (channels 4w..4w+3), `2 * groups` vectors
///   (groups = ceil(outputs / 4)): first the high bytes, then the low bytes of w + 32768,
///   component j % 4 of vector j / 4 holding output j's four channels' bytes (channels past the
///   last: weight 0, bytes 0x80 and 0). [`byte_weight_projection`] spells out the kernel's sum.
///
/// None when the level's weights do not fit the uniform.
pub(super) fn projection_uniform(
    p: &LevelPack,
    preferred: WeightLayout,
) -> Option<ProjectionLayout> {
    let (inputs, outputs) = (p.pca_in as usize, p.pca_out as usize);
    let word = |at: u32| p.words[at as usize] as i32;
    let weight =
        |a: usize, j: usize, i: usize| word(p.offsets.weights[a] + (j * inputs + i) as u32);
    if outputs > 16 {
        return None;
    }
    let groups = outputs.div_ceil(4);
    let channels = p.channels as usize;
    let words_per_pixel = channels.div_ceil(4);
    let fit_16_bits = (0..3)
        .all(|a| (0..outputs).all(|j| (0..inputs).all(|i| i16::try_from(weight(a, j, i)).is_ok())));
    let layout = match preferred {
        _ if !fit_16_bits => WeightLayout::Plain,
        WeightLayout::Bytes if inputs != PLANE_NEIGHBOURS * channels => WeightLayout::Halves,
        preferred => preferred,
    };
    let vectors = 3 * match layout {
        WeightLayout::Plain => inputs * groups,
        WeightLayout::Halves => inputs * outputs.div_ceil(8),
        WeightLayout::Bytes => PLANE_NEIGHBOURS * words_per_pixel * 2 * groups,
    };
    if PROJECTION_BASE + vectors > PROJECTION_VECTORS {
        return None;
    }
    let mut v = vec![0i32; PROJECTION_VECTORS * 4];
    for a in 0..3 {
        let mean = p.offsets.mean[a];
        for j in 0..outputs {
            v[a * 16 + j] = (0..inputs).fold(0i32, |b, i| {
                b.wrapping_add(word(mean + i as u32).wrapping_mul(weight(a, j, i)))
            });
        }
        match layout {
            WeightLayout::Plain => {
                for i in 0..inputs {
                    let row = (PROJECTION_BASE + (a * inputs + i) * groups) * 4;
                    for j in 0..outputs {
                        v[row + j] = weight(a, j, i);
                    }
                }
            }
            WeightLayout::Halves => {
                let per_input = outputs.div_ceil(8);
                for i in 0..inputs {
                    let row = (PROJECTION_BASE + (a * inputs + i) * per_input) * 4;
                    for j in 0..outputs {
                        // Output j = 8h + 4 half + c: component c of vector h, low or high half.
                        let w = weight(a, j, i);
                        v[row + (j / 8) * 4 + j % 4] |=
                            if j % 8 < 4 { w & 0xFFFF } else { w << 16 };
                    }
                }
            }
            WeightLayout::Bytes => {
                for n in 0..PLANE_NEIGHBOURS {
                    for w in 0..words_per_pixel {
                        let row = PROJECTION_BASE
                            + ((a * PLANE_NEIGHBOURS + n) * words_per_pixel + w) * 2 * groups;
                        for j in 0..groups * 4 {
                            let (mut high, mut low) = (0u32, 0u32);
                            for c in 0..4 {
                                let channel = 4 * w + c;
                                let w_ij = if j < outputs && channel < channels {
                                    weight(a, j, n * channels + channel)
                                } else {
                                    0
                                };
                                let offset = (w_ij + 32768) as u32;
                                high |= (offset >> 8) << (8 * c);
                                low |= (offset & 0xFF) << (8 * c);
                            }
                            v[(row + j / 4) * 4 + j % 4] = high as i32;
                            v[(row + groups + j / 4) * 4 + j % 4] = low as i32;
                        }
                    }
                }
            }
        }
    }
    Some(ProjectionLayout { vectors: v, layout })
}

/// What the kernel computes for output j of plane a over the bytes layout of
/// [`projection_uniform`], given the neighbours' pixel words in order: with w + 32768 = 256 H + L,
/// sum_i x_i w_i = 256 sum x_i H_i + sum x_i L_i - 32768 sum x_i, each sum over a pixel word's
/// four bytes a packed byte dot product (bytes past the channels cancel: H 0x80, L 0), minus the
/// bias. Wrapping, as the kernel's u32 sums.
#[cfg(test)]
fn byte_weight_projection(
    v: &[i32],
    a: usize,
    j: usize,
    pixel_words: &[u32],
    groups: usize,
) -> u32 {
    let dot = |x: u32, w: u32| -> u32 {
        (0..4)
            .map(|c| ((x >> (8 * c)) & 0xFF) * ((w >> (8 * c)) & 0xFF))
            .sum()
    };
    let words_per_pixel = pixel_words.len() / PLANE_NEIGHBOURS;
    let (mut high, mut low, mut sum) = (0u32, 0u32, 0u32);
    for (k, &x) in pixel_words.iter().enumerate() {
        let row = PROJECTION_BASE + (a * PLANE_NEIGHBOURS * words_per_pixel + k) * 2 * groups;
        high = high.wrapping_add(dot(x, v[(row + j / 4) * 4 + j % 4] as u32));
        low = low.wrapping_add(dot(x, v[(row + groups + j / 4) * 4 + j % 4] as u32));
        sum = sum.wrapping_add(dot(x, 0x0101_0101));
    }
    high.wrapping_mul(256)
        .wrapping_add(low)
        .wrapping_sub(sum.wrapping_mul(32768))
        .wrapping_sub(v[a * 16 + j] as u32)
}

/// A level's projection uniform ([`projection_uniform`]) and its layout.
pub(super) struct ProjectionLayout {
    pub(super) vectors: Vec<i32>,
    pub(super) layout: WeightLayout,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::level::LevelOffsets;

    /// The kernel reads the projection uniform with the layout's constants.
    #[test]
    fn the_kernel_reads_the_projection_uniform_as_laid_out() {
        let source = crate::gpu::shaders::source("correct");
        for constant in [
            format!("const PROJECTION_BASE: u32 = {}u;", PROJECTION_BASE),
            format!("const PROJECTION_VECTORS: u32 = {}u;", PROJECTION_VECTORS),
        ] {
            assert!(source.contains(&constant), "{constant}");
        }
    }

    /// A level of random 16-bit weights and means: `channels` per neighbour, `outputs` outputs.
    fn random_pack(channels: usize, outputs: usize, seed: u32) -> LevelPack {
        let inputs = PLANE_NEIGHBOURS * channels;
        let mut words = Vec::new();
        let mut offsets = LevelOffsets::default();
        let mut rng = seed;
        let mut next = move || {
            rng = crate::util::hash::hash32(rng);
            rng
        };
        for a in 0..3 {
            offsets.mean[a] = words.len() as u32;
            words.extend((0..inputs).map(|_| next() % 256));
            offsets.weights[a] = words.len() as u32;
            // The extremes of 16 bits included.
            words.extend((0..inputs * outputs).map(|k| match k % 97 {
                0 => -32768i32 as u32,
                1 => 32767,
                _ => ((next() % 65536) as i32 - 32768) as u32,
            }));
        }
        LevelPack {
            words,
            offsets,
            width: 1,
            height: 1,
            channels: channels as u32,
            color_channels: channels.min(3) as u32,
            pixel_words: channels.div_ceil(4) as u32,
            pca_in: inputs as u32,
            pca_out: outputs as u32,
            shift: 16,
            proj_words: outputs.div_ceil(4) as u32,
            k2d: 2,
            k3d_stride: 4,
            shared: false,
        }
    }

    /// The kernel's projection over the uniform's layout equals the reference's
    /// sum_i (x_i - mean_i) w_ji for every plane and output, in each layout (bytes: whatever the
    /// bytes past the channels hold), and with a weight beyond 16 bits in the plain one.
    #[test]
    fn projection_uniform_reproduces_the_centred_projection() {
        for (channels, outputs) in [(3usize, 8usize), (4, 12), (3, 10), (6, 16), (1, 4)] {
            let inputs = PLANE_NEIGHBOURS * channels;
            let words_per_pixel = channels.div_ceil(4);
            let groups = outputs.div_ceil(4);
            let mut rng = 777u32 + channels as u32;
            let mut next = move || {
                rng = crate::util::hash::hash32(rng);
                rng
            };
            // Extreme inputs included.
            let x: Vec<i32> = (0..inputs)
                .map(|i| match i % 31 {
                    0 => 0,
                    1 => 255,
                    _ => (next() % 256) as i32,
                })
                .collect();
            // The neighbours' pixel words as the state holds them, random bytes past the channels.
            let pixel_words: Vec<u32> = (0..PLANE_NEIGHBOURS * words_per_pixel)
                .map(|k| {
                    let (n, w) = (k / words_per_pixel, k % words_per_pixel);
                    (0..4).fold(0u32, |word, c| {
                        let channel = 4 * w + c;
                        let byte = if channel < channels {
                            x[n * channels + channel] as u32
                        } else {
                            next() % 256
                        };
                        word | byte << (8 * c)
                    })
                })
                .collect();
            let reference = |pack: &LevelPack, a: usize, j: usize| -> i64 {
                let word = |at: u32| pack.words[at as usize] as i32;
                (0..inputs)
                    .map(|i| {
                        let w = word(pack.offsets.weights[a] + (j * inputs + i) as u32);
                        (x[i] - word(pack.offsets.mean[a] + i as u32)) as i64 * w as i64
                    })
                    .sum()
            };
            let pack = random_pack(channels, outputs, 12345 + channels as u32);
            // The kernel's sum over the halves or plain layout (halves: a vector component's low
            // or high half, sign-extended).
            let by_input = |layout: &ProjectionLayout, a: usize, j: usize| -> i32 {
                let v = &layout.vectors;
                let per_input = match layout.layout {
                    WeightLayout::Halves => outputs.div_ceil(8),
                    _ => groups,
                };
                (0..inputs).fold(v[a * 16 + j].wrapping_neg(), |acc, i| {
                    let row = (PROJECTION_BASE + (a * inputs + i) * per_input) * 4;
                    let w = match layout.layout {
                        WeightLayout::Halves => {
                            let w = v[row + (j / 8) * 4 + j % 4];
                            if j % 8 < 4 {
                                (w << 16) >> 16
                            } else {
                                w >> 16
                            }
                        }
                        _ => v[row + j],
                    };
                    acc.wrapping_add(x[i].wrapping_mul(w))
                })
            };
            for preferred in [
                WeightLayout::Halves,
                WeightLayout::Bytes,
                WeightLayout::Plain,
            ] {
                let layout = projection_uniform(&pack, preferred).unwrap();
                assert_eq!(
                    layout.layout, preferred,
                    "{channels} channels, {outputs} outputs"
                );
                for a in 0..3 {
                    for j in 0..outputs {
                        let kernel = if preferred == WeightLayout::Bytes {
                            byte_weight_projection(&layout.vectors, a, j, &pixel_words, groups)
                                as i32
                        } else {
                            by_input(&layout, a, j)
                        };
                        assert_eq!(
                            kernel as i64,
                            reference(&pack, a, j),
                            "plane {a} output {j}"
                        );
                    }
                }
                // One weight beyond 16 bits: the plain layout whatever was preferred.
                let mut wide = pack.clone();
                wide.words[wide.offsets.weights[1] as usize + 7] = 40_000;
                let layout = projection_uniform(&wide, preferred).unwrap();
                assert_eq!(layout.layout, WeightLayout::Plain);
                for a in 0..3 {
                    for j in 0..outputs {
                        let kernel = by_input(&layout, a, j);
                        assert_eq!(
                            kernel as i64,
                            reference(&wide, a, j),
                            "plane {a} output {j}"
                        );
                    }
                }
            }
        }
        // Too many inputs for the uniform (in either layout): refused, not truncated.
        for preferred in [WeightLayout::Halves, WeightLayout::Bytes] {
            assert!(projection_uniform(&random_pack(28, 16, 1), preferred).is_none());
        }
        let mut wide = random_pack(28, 16, 1);
        wide.words[wide.offsets.weights[0] as usize] = 40_000;
        assert!(projection_uniform(&wide, WeightLayout::Halves).is_none());
    }
}
