//! KTX2 3D textures (Khronos KTX 2.0): a volume as one 3D texture, depth = z, for engines that
//! load KTX2 (Bevy, Unity and Unreal plug-ins, `ktx` tools). One colour channel gives
//! `VK_FORMAT_R8_UNORM`, any other count `VK_FORMAT_R8G8B8A8_UNORM` (missing channels filled:
//! grey replicated, alpha opaque); `srgb` gives the `_SRGB` variants. With `mips`, the full
//! mip chain by 2x2x2 box filtering (rounded means, clipped at odd edges).
//!
//! Layout (KTX 2.0 specification, sections 3-4): identifier, header, index, level index (level
//! 0 first), a basic data format descriptor, one key/value pair (`KTXwriter`), then the levels'
//! data smallest first, each at a multiple of 4 bytes; no supercompression.

use crate::error::{Error, Result};
use crate::volume::Volume;

const IDENTIFIER: [u8; 12] = [
    0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A,
];
pub const VK_FORMAT_R8_UNORM: u32 = 9;
pub const VK_FORMAT_R8_SRGB: u32 = 15;
pub const VK_FORMAT_R8G8B8A8_UNORM: u32 = 37;
pub const VK_FORMAT_R8G8B8A8_SRGB: u32 = 43;

/// The largest side written: the 3D texture limit every Vulkan, Metal and D3D12 device meets
/// (wgpu's default `max_texture_dimension_3d`).
pub const MAX_SIDE: u32 = 2048;

/// How a volume becomes a texture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TextureOptions {
    /// Colour values are sRGB-encoded (the `_SRGB` formats; alpha stays linear).
    pub srgb: bool,
    /// Write the full mip chain.
    pub mips: bool,
}

/// The texels of `v` as the texture stores them: one byte (one channel) or RGBA.
fn texels(v: &Volume) -> (Vec<u8>, usize) {
    let c = v.channels as usize;
    if c == 1 {
        return (v.data.clone(), 1);
    }
    let mut out = Vec::with_capacity(v.data.len() / c * 4);
    for p in v.data.chunks_exact(c) {
        out.extend_from_slice(&match c {
            2 => [p[0], p[0], p[0], p[1]],
            3 => [p[0], p[1], p[2], 255],
            _ => [p[0], p[1], p[2], p[3]],
        });
    }
    (out, 4)
}

/// One mip level down: each texel the rounded mean of the up-to-2x2x2 texels it covers.
fn downsample(data: &[u8], dims: [usize; 3], texel: usize) -> (Vec<u8>, [usize; 3]) {
    let next = dims.map(|d| (d / 2).max(1));
    let mut out = vec![0u8; next[0] * next[1] * next[2] * texel];
    for z in 0..next[2] {
        for y in 0..next[1] {
            for x in 0..next[0] {
                let mut sum = [0u32; 4];
                let mut count = 0u32;
                for sz in (2 * z)..(2 * z + 2).min(dims[2]) {
                    for sy in (2 * y)..(2 * y + 2).min(dims[1]) {
                        for sx in (2 * x)..(2 * x + 2).min(dims[0]) {
                            let i = ((sz * dims[1] + sy) * dims[0] + sx) * texel;
                            for c in 0..texel {
                                sum[c] += data[i + c] as u32;
                            }
                            count += 1;
                        }
                    }
                }
                let o = ((z * next[1] + y) * next[0] + x) * texel;
                for c in 0..texel {
                    out[o + c] = ((sum[c] + count / 2) / count) as u8;
                }
            }
        }
    }
    (out, next)
}

/// The basic data format descriptor of an 8-bit R or RGBA format (KHR Data Format 1.3).
fn data_format_descriptor(texel: usize, srgb: bool) -> Vec<u8> {
    let samples: &[u32] = if texel == 1 { &[0] } else { &[0, 1, 2, 15] };
    let block_size = 24 + 16 * samples.len() as u32;
    let mut words = vec![
        4 + block_size, // dfdTotalSize
        0,              // vendorId 0 (Khronos), descriptorType 0 (basic)
        2 | (block_size << 16),
        // Colour model RGBSDA, BT.709 primaries, linear or sRGB transfer, straight alpha.
        1 | (1 << 8) | (if srgb { 2 } else { 1 } << 16),
        0,            // texel block 1x1x1x1
        texel as u32, // bytes in plane 0
        0,
    ];
    for (i, &channel) in samples.iter().enumerate() {
        // Alpha is linear even in an sRGB format (KHR_DF_SAMPLE_DATATYPE_LINEAR).
        let linear = if srgb && channel == 15 { 0x10 } else { 0 };
        words.push((i as u32 * 8) | (7 << 16) | ((channel | linear) << 24));
        words.push(0); // sample position
        words.push(0); // lower
        words.push(255); // upper
    }
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// The key/value data: the writer's name, padded to 4 bytes.
fn key_values() -> Vec<u8> {
    let pair = format!("KTXwriter\0solidsynth {}\0", env!("CARGO_PKG_VERSION"));
    let mut out = (pair.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(pair.as_bytes());
    out.resize(out.len().div_ceil(4) * 4, 0);
    out
}

/// Refuse a volume the format cannot hold as one 3D texture (`what` names the output).
pub fn check(dims: [u32; 3], what: &str) -> Result<()> {
    if dims.iter().any(|&d| d > MAX_SIDE) {
        return Err(Error::invalid(
            what,
            format!(
                "a KTX2 3D texture is at most {MAX_SIDE} texels a side (devices' limit); the \
                 volume is {}x{}x{}",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    Ok(())
}

/// The KTX2 file of `v`; an error for a volume with a zero side, other than 1 to 4 channels,
/// data that does not match its sizes, or a side over [`MAX_SIDE`].
pub fn to_bytes(v: &Volume, options: TextureOptions) -> Result<Vec<u8>> {
    crate::io::slab_order::check_dims(v.dims(), v.channels)?;
    v.check("volume")?;
    check(v.dims(), "volume")?;
    let (base, texel) = texels(v);
    let mut levels = vec![base];
    let mut dims = [v.nx as usize, v.ny as usize, v.nz as usize];
    if options.mips {
        while dims.iter().any(|&d| d > 1) {
            let (next, next_dims) = downsample(levels.last().expect("a level"), dims, texel);
            levels.push(next);
            dims = next_dims;
        }
    }
    let vk_format = match (texel, options.srgb) {
        (1, false) => VK_FORMAT_R8_UNORM,
        (1, true) => VK_FORMAT_R8_SRGB,
        (_, false) => VK_FORMAT_R8G8B8A8_UNORM,
        (_, true) => VK_FORMAT_R8G8B8A8_SRGB,
    };
    let dfd = data_format_descriptor(texel, options.srgb);
    let kvd = key_values();
    let level_index_at = 80;
    let dfd_at = level_index_at + 24 * levels.len();
    let kvd_at = dfd_at + dfd.len();
    let mut data_at = (kvd_at + kvd.len()).div_ceil(4) * 4;
    // Smallest level first in the file.
    let mut offsets = vec![0usize; levels.len()];
    for (i, level) in levels.iter().enumerate().rev() {
        offsets[i] = data_at;
        data_at = (data_at + level.len()).div_ceil(4) * 4;
    }
    let mut out = Vec::with_capacity(data_at);
    out.extend_from_slice(&IDENTIFIER);
    for word in [
        vk_format,
        1, // typeSize: bytes of one component
        v.nx,
        v.ny,
        v.nz,
        0, // layerCount: not an array
        1, // faceCount
        levels.len() as u32,
        0, // supercompression: none
        dfd_at as u32,
        dfd.len() as u32,
        kvd_at as u32,
        kvd.len() as u32,
    ] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&0u64.to_le_bytes()); // sgdByteOffset
    out.extend_from_slice(&0u64.to_le_bytes()); // sgdByteLength
    for (level, &offset) in levels.iter().zip(&offsets) {
        for value in [offset, level.len(), level.len()] {
            out.extend_from_slice(&(value as u64).to_le_bytes());
        }
    }
    out.extend_from_slice(&dfd);
    out.extend_from_slice(&kvd);
    for (i, level) in levels.iter().enumerate().rev() {
        out.resize(offsets[i], 0);
        out.extend_from_slice(level);
    }
    out.resize(data_at, 0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mips_average_and_end_at_one_texel() {
        let mut v = Volume::new(4, 2, 3, 1);
        v.data = (0..24).map(|i| i as u8 * 10).collect();
        let bytes = to_bytes(
            &v,
            TextureOptions {
                srgb: false,
                mips: true,
            },
        )
        .unwrap();
        assert_eq!(&bytes[..12], &IDENTIFIER);
        let word = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
        assert_eq!(word(12), VK_FORMAT_R8_UNORM);
        assert_eq!(word(12 + 7 * 4), 3, "4x2x3 -> 2x1x1 -> 1x1x1");
        let (l1, d1) = downsample(&v.data, [4, 2, 3], 1);
        assert_eq!(d1, [2, 1, 1]);
        // Texel (0, 0, 0) of level 1 covers x 0-1, y 0-1, z 0-1: values 0,10,40,50,80,90,120,130.
        assert_eq!(l1[0], 65);
    }
}
