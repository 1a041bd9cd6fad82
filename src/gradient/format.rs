//! The `.gsolid` file: a gradient solid's control grid.
//!
//! Little-endian. Header (68 bytes): magic `GSOLID\0\0`, u32 version (2), u32 nx, ny, nz (control
//! points per axis), u32 spacing (voxels, 4), u32 channels, u32 encoding (0: f32, 1: 8-bit),
//! u64 payload length, u32 CRC-32 (of header bytes 0..44 and 48..68, then the payload), u32
//! detail channels (0, or half the channels: the trailing ones hold the detail residual's sigma,
//! paper 5.4), u32 size x, y, z (the voxels the solid stands for: a vectorized volume's size, a
//! synthesized solid's period), u32 flags (bit 0: periodic with period `size`). Version 1 files
//! (52 bytes of header, read too) end at the detail channels, their CRC covering bytes 0..44;
//! they stand for their control grid's extent, d (n - 1) + 1 voxels, and are not periodic.
//! Payload: per point (x fastest), per channel, the four values f, df/dx, df/dy, df/dz.
//! - f32: the values as f32.
//! - 8-bit: first, per (channel, component), an f32 minimum and an f32 step; then each value as
//!   one byte q, standing for minimum + q * step. A quarter of the f32 size.

use super::{GradientSolid, SPACING};
use crate::error::{Error, Result};

const MAGIC: &[u8; 8] = b"GSOLID\0\0";
const VERSION: u32 = 2;
const HEADER: usize = 68;
/// The header of version 1 files, which lack the size and flags.
const HEADER_V1: usize = 52;
/// Bit 0 of the flags: periodic.
const PERIODIC: u32 = 1;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Encoding {
    F32,
    /// 8 bits per value with a per-(channel, component) range.
    U8,
}

/// CRC-32 of the header's fields (bytes 0..44, and past the CRC, 48.., for version 2) and the
/// payload.
fn checksum(header: &[u8], payload: &[u8]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(&header[..44]);
    if header.len() > HEADER_V1 {
        h.update(&header[48..]);
    }
    h.update(payload);
    h.finalize()
}

/// Values (`comps` interleaved components) in `encoding`: f32 as is, or 8-bit with a per-component
/// (minimum, step) pair first.
pub(crate) fn encode_values(values: &[f32], comps: usize, encoding: Encoding) -> Vec<u8> {
    let mut payload = Vec::new();
    match encoding {
        Encoding::F32 => payload.extend(values.iter().flat_map(|v| v.to_le_bytes())),
        Encoding::U8 => {
            let mut lo = vec![f32::INFINITY; comps];
            let mut hi = vec![f32::NEG_INFINITY; comps];
            for (i, &v) in values.iter().enumerate() {
                lo[i % comps] = lo[i % comps].min(v);
                hi[i % comps] = hi[i % comps].max(v);
            }
            // No values: an empty range (still a valid pair).
            let lo: Vec<f32> = lo
                .iter()
                .map(|&l| if l.is_finite() { l } else { 0.0 })
                .collect();
            let step: Vec<f32> = (0..comps)
                .map(|c| ((hi[c] - lo[c]) / 255.0).max(f32::MIN_POSITIVE))
                .collect();
            for c in 0..comps {
                payload.extend(lo[c].to_le_bytes());
                payload.extend(step[c].to_le_bytes());
            }
            payload.extend(values.iter().enumerate().map(|(i, &v)| {
                let c = i % comps;
                ((v - lo[c]) / step[c]).round().clamp(0.0, 255.0) as u8
            }));
        }
    }
    payload
}

/// The inverse of [`encode_values`] for `count` values; None when the length does not match or a
/// value is not finite.
pub(crate) fn decode_values(
    payload: &[u8],
    comps: usize,
    count: usize,
    encoding: Encoding,
) -> Option<Vec<f32>> {
    let f = |b: &[u8]| f32::from_le_bytes(b.try_into().unwrap());
    let data: Vec<f32> = match encoding {
        Encoding::F32 => {
            if payload.len() != count.checked_mul(4)? {
                return None;
            }
            payload.chunks_exact(4).map(f).collect()
        }
        Encoding::U8 => {
            if payload.len() != comps.checked_mul(8)?.checked_add(count)? {
                return None;
            }
            let ranges: Vec<(f32, f32)> = (0..comps)
                .map(|c| {
                    (
                        f(&payload[c * 8..c * 8 + 4]),
                        f(&payload[c * 8 + 4..c * 8 + 8]),
                    )
                })
                .collect();
            payload[comps * 8..]
                .iter()
                .enumerate()
                .map(|(i, &q)| ranges[i % comps].0 + q as f32 * ranges[i % comps].1)
                .collect()
        }
    };
    data.iter().all(|v| v.is_finite()).then_some(data)
}

pub fn to_bytes(s: &GradientSolid, encoding: Encoding) -> Vec<u8> {
    let payload = encode_values(&s.data, s.channels as usize * 4, encoding);
    let mut out = Vec::with_capacity(HEADER + payload.len());
    out.extend_from_slice(MAGIC);
    for v in [
        VERSION,
        s.dims[0],
        s.dims[1],
        s.dims[2],
        SPACING,
        s.channels,
        (encoding == Encoding::U8) as u32,
    ] {
        out.extend(v.to_le_bytes());
    }
    out.extend((payload.len() as u64).to_le_bytes());
    let crc_at = out.len();
    out.extend([0; 4]);
    out.extend(s.detail.to_le_bytes());
    for v in s.size {
        out.extend(v.to_le_bytes());
    }
    out.extend((if s.periodic { PERIODIC } else { 0 }).to_le_bytes());
    let crc = checksum(&out, &payload);
    out[crc_at..crc_at + 4].copy_from_slice(&crc.to_le_bytes());
    out.extend(payload);
    out
}

/// Parse a `.gsolid`; `name` labels errors.
pub fn from_bytes(bytes: &[u8], name: &str) -> Result<GradientSolid> {
    let bad = |why: String| Error::invalid(name, why);
    if bytes.len() < HEADER_V1 || &bytes[..8] != MAGIC {
        return Err(bad("not a .gsolid file (bad magic or too short)".into()));
    }
    let word = |i: usize| u32::from_le_bytes(bytes[8 + 4 * i..12 + 4 * i].try_into().unwrap());
    let header = match word(0) {
        1 => HEADER_V1,
        VERSION if bytes.len() >= HEADER => HEADER,
        VERSION => return Err(bad("the header is cut short".into())),
        other => {
            return Err(bad(format!(
                "unsupported .gsolid version {other} (this build reads 1 and {VERSION})"
            )))
        }
    };
    let dims = [word(1), word(2), word(3)];
    let (spacing, channels, encoding) = (word(4), word(5), word(6));
    if spacing != SPACING {
        return Err(bad(format!(
            "control spacing {spacing}, only {SPACING} is supported"
        )));
    }
    if encoding > 1 {
        return Err(bad(format!("unknown encoding {encoding}")));
    }
    if dims.iter().any(|&d| !(2..=4096).contains(&d)) || !(1..=16).contains(&channels) {
        return Err(bad(format!(
            "declares a grid of {}x{}x{} cells with {channels} channels; a grid is 2..=4096 \
             cells a side, with 1..=16 channels",
            dims[0], dims[1], dims[2]
        )));
    }
    let len = u64::from_le_bytes(bytes[36..44].try_into().unwrap());
    let crc = u32::from_le_bytes(bytes[44..48].try_into().unwrap());
    let detail = u32::from_le_bytes(bytes[48..52].try_into().unwrap());
    if detail != 0 && detail.checked_mul(2) != Some(channels) {
        return Err(bad(format!(
            "{detail} detail channels in a solid of {channels}: expected 0 or half"
        )));
    }
    if len != (bytes.len() - header) as u64 {
        return Err(bad(format!(
            "payload length {len} but {} bytes follow the header",
            bytes.len() - header
        )));
    }
    let payload = &bytes[header..];
    if checksum(&bytes[..header], payload) != crc {
        return Err(bad("checksum mismatch: the file is corrupt".into()));
    }
    let values = dims.iter().map(|&d| d as usize).product::<usize>() * channels as usize * 4;
    let comps = channels as usize * 4;
    let encoding = if encoding == 0 {
        Encoding::F32
    } else {
        Encoding::U8
    };
    let data = decode_values(payload, comps, values, encoding).ok_or_else(|| {
        bad(format!(
            "payload of {} bytes does not hold {values} finite values",
            payload.len()
        ))
    })?;
    let mut s = GradientSolid::new(dims, channels)?;
    s.data = data;
    s.detail = detail;
    if header == HEADER {
        s.size = [11, 12, 13].map(word);
        let flags = word(14);
        if flags & !PERIODIC != 0 {
            return Err(bad(format!("unknown flags {flags:#x}")));
        }
        s.periodic = flags & PERIODIC != 0;
        s.check().map_err(|e| match e {
            Error::InvalidInput { problem, .. } => bad(problem),
            other => other,
        })?;
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> GradientSolid {
        let mut s = GradientSolid::new([3, 2, 4], 3).unwrap();
        let mut rng = crate::util::hash::SeededRng::new(1);
        for v in s.data.iter_mut() {
            *v = rng.below(25600) as f32 / 100.0 - 20.0;
        }
        s
    }

    #[test]
    fn round_trips() {
        let s = sample();
        assert_eq!(from_bytes(&to_bytes(&s, Encoding::F32), "t").unwrap(), s);
        let q = from_bytes(&to_bytes(&s, Encoding::U8), "t").unwrap();
        let worst = s
            .data
            .iter()
            .zip(&q.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0f32, f32::max);
        // Half a step of a 276-wide range over 255 levels.
        assert!(worst <= 276.0 / 255.0 / 2.0 + 1e-3, "{worst}");
        assert!(to_bytes(&s, Encoding::U8).len() * 2 < to_bytes(&s, Encoding::F32).len());
    }

    #[test]
    fn the_size_and_periodicity_round_trip_and_version_1_still_reads() {
        let periodic = sample().into_periodic();
        assert_eq!(periodic.size, [8, 4, 12]);
        let back = from_bytes(&to_bytes(&periodic, Encoding::F32), "t").unwrap();
        assert!(back.periodic && back.size == [8, 4, 12]);
        let mut vectorized = sample();
        vectorized.size = [7, 2, 13];
        assert_eq!(
            from_bytes(&to_bytes(&vectorized, Encoding::U8), "t")
                .unwrap()
                .size,
            [7, 2, 13]
        );
        // A size past the grid is refused, naming the file.
        vectorized.size = [7, 2, 14];
        let e = from_bytes(&to_bytes(&vectorized, Encoding::U8), "t.gsolid").unwrap_err();
        assert!(
            e.to_string().contains("t.gsolid: stands for [7, 2, 14]"),
            "{e}"
        );
        // Version 1: the same bytes without the size and flags, read as the grid's extent.
        let v2 = to_bytes(&periodic, Encoding::F32);
        let mut v1 = [&v2[..HEADER_V1], &v2[HEADER..]].concat();
        v1[8..12].copy_from_slice(&1u32.to_le_bytes());
        let crc = checksum(&v1[..HEADER_V1], &v1[HEADER_V1..]);
        v1[44..48].copy_from_slice(&crc.to_le_bytes());
        let old = from_bytes(&v1, "old.gsolid").unwrap();
        assert_eq!((old.size, old.periodic), ([9, 5, 13], false));
        assert_eq!(old.data, periodic.data);
    }

    #[test]
    fn corrupt_files_are_refused_never_panic() {
        let good = to_bytes(&sample(), Encoding::U8);
        assert!(from_bytes(&good[..good.len() - 1], "t").is_err());
        let mut rng = crate::util::hash::SeededRng::new(5);
        for _ in 0..3000 {
            let mut b = good.clone();
            for _ in 0..1 + rng.below(3) {
                let i = rng.below(b.len() as u64) as usize;
                b[i] ^= 1 << rng.below(8);
            }
            if rng.below(3) == 0 {
                b.truncate(rng.below(b.len() as u64) as usize);
            }
            // Any change to the header or payload is caught (checksum, sizes, fields); two flips
            // of the same bit cancel out.
            if b != good {
                assert!(from_bytes(&b, "t").is_err());
            }
        }
    }

    /// Mutations with the checksum recomputed, so that the structure checks behind it are
    /// what meets them: the parser returns an error or a consistent solid, never panics or
    /// allocates what the file does not hold.
    #[test]
    fn fuzz_structure_behind_a_valid_checksum() {
        let mut rng = crate::util::hash::SeededRng::new(6);
        let (mut accepted, mut refused) = (0, 0);
        for round in 0..4000 {
            let encoding = if round % 2 == 0 {
                Encoding::U8
            } else {
                Encoding::F32
            };
            let mut b = to_bytes(&sample(), encoding);
            for _ in 0..1 + rng.below(4) {
                // Mostly the header fields (dims, channels, encoding, length, detail).
                let i = if rng.below(2) == 0 {
                    8 + rng.below(HEADER as u64 - 8) as usize
                } else {
                    rng.below(b.len() as u64) as usize
                };
                if (44..48).contains(&i) {
                    continue;
                }
                b[i] = match rng.below(3) {
                    0 => b[i] ^ (1 << rng.below(8)),
                    1 => rng.below(256) as u8,
                    _ => [0, 1, 2, 255][rng.below(4) as usize],
                };
            }
            if rng.below(4) == 0 {
                b.truncate(HEADER + rng.below((b.len() - HEADER) as u64) as usize);
            }
            let header = HEADER.min(b.len());
            let crc = checksum(&b[..header], &b[header..]);
            b[44..48].copy_from_slice(&crc.to_le_bytes());
            match from_bytes(&b, "fuzz.gsolid") {
                Ok(s) => {
                    accepted += 1;
                    let points: usize = s.dims.iter().map(|&d| d as usize).product();
                    assert_eq!(s.data.len(), points * s.channels as usize * 4);
                    assert!(s.data.iter().all(|v| v.is_finite()));
                }
                Err(e) => {
                    refused += 1;
                    // The error names the input.
                    assert!(e.to_string().contains("fuzz.gsolid"), "{e}");
                }
            }
        }
        // Both outcomes occur (payload-only changes stay valid files).
        assert!(
            accepted > 100 && refused > 100,
            "{accepted} accepted, {refused} refused"
        );
    }
}
