//! The `.ssa` analysis file: everything synthesis needs, self-contained and versioned.
//!
//! Layout (little-endian):
//! ```text
//! 0   magic    8 bytes  "SOLIDSSA"
//! 8   version  u32      FORMAT_VERSION
//! 12  flags    u32      0
//! 16  length   u64      payload bytes
//! 24  crc32    u32      CRC-32 (IEEE) of the payload
//! 28  reserved u32      0
//! 32  payload:
//!   params     pca_dims[4] k2d[4] strips crossbar_keep max_3d max_filter_rounds (u32)
//!              feature_weight (f32) balance_rounds (u32) balance_strength (f32)
//!   header     border color_channels has_feature shared exemplar_count level_count (u32)
//!   per exemplar (1 or 3), per level (finest first):
//!     image    width height channels (u32), pixels (u8, padded to 4 bytes)
//!     pca      input_dims output_dims shift (u32), mean [i32; D], weights [i32; K*D],
//!              eigenvalues [f32; D]
//!     projected       [u32; pixels * ceil(K/4)]
//!     candidates_2d   [u32; pixels * k2d]              packed x | y << 16
//!     has_3d (u32); if 1:
//!       candidates_3d [u32; pixels * max_3d * 3]       unused slots 0xFFFFFFFF
//!       counts_3d     [u8; pixels] (padded to 4 bytes)
//!       slab          [u32; pixels * 3]
//!     penalty  [u8; pixels] (padded to 4 bytes)         usage penalties, see analysis::balance
//!     stats    mean_best_cb (f64), filter_rounds (u32)
//! ```
//! Version 2 added the balancing parameters and the penalties.
//! Loading checks the magic, version, length and checksum first, then every size and coordinate,
//! so a damaged or hostile file is an error, never a panic or an out-of-bounds read later.

use crate::analysis::frame::{pack, unpack, NO_COORD};
use crate::analysis::pca::PcaBasis;
use crate::analysis::{
    Analysis, AnalysisParams, ExemplarData, LevelData, LevelStats, ANALYSED_LEVELS,
};
use crate::error::{Error, Result};
use crate::exemplar::{Border, Image};
use std::path::Path;

pub const MAGIC: &[u8; 8] = b"SOLIDSSA";
pub const FORMAT_VERSION: u32 = 2;
const HEADER_LEN: usize = 32;

struct Writer(Vec<u8>);

impl Writer {
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn bytes_padded(&mut self, b: &[u8]) {
        self.0.extend_from_slice(b);
        self.0.resize(self.0.len().next_multiple_of(4), 0);
    }
    fn u32s(&mut self, v: &[u32]) {
        v.iter().for_each(|&x| self.u32(x));
    }
    fn i32s(&mut self, v: &[i32]) {
        v.iter().for_each(|&x| self.u32(x as u32));
    }
}

/// Serialize an analysis to bytes (deterministic: same analysis, same bytes).
pub fn to_bytes(a: &Analysis) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    let p = &a.params;
    w.u32s(&p.pca_dims);
    w.u32s(&p.k2d);
    w.u32s(&[
        p.strips_per_axis,
        p.crossbar_keep,
        p.max_3d,
        p.max_filter_rounds,
    ]);
    w.f32(p.feature_weight);
    w.u32(p.balance_rounds);
    w.f32(p.balance_strength);
    w.u32s(&[
        a.border.code(),
        a.color_channels,
        a.has_feature as u32,
        a.shared as u32,
        a.exemplars.len() as u32,
        a.level_count() as u32,
    ]);
    for ex in &a.exemplars {
        for l in &ex.levels {
            w.u32s(&[l.image.width, l.image.height, l.image.channels]);
            w.bytes_padded(&l.image.pixels);
            w.u32s(&[l.pca.input_dims, l.pca.output_dims, l.pca.shift]);
            w.i32s(&l.pca.mean);
            w.i32s(&l.pca.weights);
            l.pca.eigenvalues.iter().for_each(|&e| w.f32(e));
            w.u32s(&l.projected);
            w.u32s(&l.candidates_2d);
            let has_3d = !l.candidates_3d.is_empty();
            w.u32(has_3d as u32);
            if has_3d {
                l.candidates_3d.iter().for_each(|t| w.u32s(t));
                w.bytes_padded(&l.counts_3d);
                l.slab.iter().for_each(|t| w.u32s(t));
            }
            w.bytes_padded(&l.penalty);
            w.f64(l.stats.mean_best_cb);
            w.u32(l.stats.filter_rounds);
        }
    }
    let payload = w.0;
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&payload);
    out
}

/// Write an analysis file atomically.
pub fn save(a: &Analysis, path: &Path) -> Result<()> {
    crate::io::atomic::write_file(path, &to_bytes(a))
}

/// Read an analysis file.
pub fn load(path: &Path) -> Result<Analysis> {
    let bytes = crate::io::input::read(path)?;
    from_bytes(&bytes).map_err(|problem| Error::corrupt(path, problem))
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

type R<T> = std::result::Result<T, String>;

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> R<&'a [u8]> {
        if self.b.len() - self.at < n {
            return Err(format!(
                "truncated: needed {n} bytes at offset {}",
                self.at + HEADER_LEN
            ));
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u32(&mut self) -> R<u32> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn f32(&mut self) -> R<f32> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn f64(&mut self) -> R<f64> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    /// `n` u32s, refusing before allocating if the file cannot hold them.
    fn u32s(&mut self, n: usize) -> R<Vec<u32>> {
        let bytes = self.take(n.checked_mul(4).ok_or("size overflow")?)?;
        Ok(bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }
    fn bytes_padded(&mut self, n: usize) -> R<Vec<u8>> {
        let v = self.take(n)?.to_vec();
        self.take(n.next_multiple_of(4) - n)?;
        Ok(v)
    }
}

fn check(cond: bool, msg: impl FnOnce() -> String) -> R<()> {
    if cond {
        Ok(())
    } else {
        Err(msg())
    }
}

/// Parse and validate an analysis file's bytes; the error says what is wrong.
pub fn from_bytes(bytes: &[u8]) -> R<Analysis> {
    check(bytes.len() >= HEADER_LEN, || {
        format!("too short for a .ssa header ({} bytes)", bytes.len())
    })?;
    check(&bytes[..8] == MAGIC, || {
        "not a solidsynth analysis file (wrong magic)".into()
    })?;
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    check(version == FORMAT_VERSION, || {
        format!("format version {version}, this solidsynth reads version {FORMAT_VERSION}; re-run `solidsynth analyze`")
    })?;
    let flags = u32::from_le_bytes(bytes[12..16].try_into().unwrap());
    let reserved = u32::from_le_bytes(bytes[28..32].try_into().unwrap());
    check(flags == 0 && reserved == 0, || {
        format!("unknown header flags {flags:#x} / reserved word {reserved:#x} (damaged, or written by a newer solidsynth)")
    })?;
    let len = u64::from_le_bytes(bytes[16..24].try_into().unwrap());
    let crc = u32::from_le_bytes(bytes[24..28].try_into().unwrap());
    let payload = &bytes[HEADER_LEN..];
    check(payload.len() as u64 == len, || {
        format!(
            "payload is {} bytes but the header says {len} (truncated or padded)",
            payload.len()
        )
    })?;
    check(crc32fast::hash(payload) == crc, || {
        "checksum mismatch: the file is damaged".into()
    })?;
    parse_payload(payload)
}

/// Parse a payload whose checksum already matched (public for fuzzing the structure checks).
pub fn parse_payload(payload: &[u8]) -> R<Analysis> {
    let mut r = Reader { b: payload, at: 0 };
    let arr = |r: &mut Reader| -> R<[u32; ANALYSED_LEVELS]> {
        let v = r.u32s(ANALYSED_LEVELS)?;
        Ok(v.try_into().unwrap())
    };
    let params = AnalysisParams {
        pca_dims: arr(&mut r)?,
        k2d: arr(&mut r)?,
        strips_per_axis: r.u32()?,
        crossbar_keep: r.u32()?,
        max_3d: r.u32()?,
        max_filter_rounds: r.u32()?,
        feature_weight: r.f32()?,
        balance_rounds: r.u32()?,
        balance_strength: r.f32()?,
    };
    params
        .validate()
        .map_err(|e| format!("bad parameters: {e}"))?;
    let border = Border::from_code(r.u32()?).ok_or("unknown border mode")?;
    let color_channels = r.u32()?;
    check(matches!(color_channels, 1 | 3 | 4), || {
        format!("{color_channels} colour channels")
    })?;
    let has_feature = match r.u32()? {
        0 => false,
        1 => true,
        v => return Err(format!("bad feature flag {v}")),
    };
    let shared = match r.u32()? {
        0 => false,
        1 => true,
        v => return Err(format!("bad shared flag {v}")),
    };
    let exemplar_count = r.u32()? as usize;
    check(exemplar_count == if shared { 1 } else { 3 }, || {
        format!("{exemplar_count} exemplars with shared = {shared}")
    })?;
    let level_count = r.u32()? as usize;
    check(level_count == ANALYSED_LEVELS, || {
        format!("{level_count} levels, expected {ANALYSED_LEVELS}")
    })?;
    let channels = color_channels + has_feature as u32;
    let k3 = params.max_3d as usize;

    let mut exemplars = Vec::new();
    for e in 0..exemplar_count {
        let mut levels: Vec<LevelData> = Vec::new();
        for level in 0..level_count {
            let (w, h, c) = (r.u32()?, r.u32()?, r.u32()?);
            check(c == channels, || {
                format!("exemplar {e} level {level}: {c} channels, expected {channels}")
            })?;
            match levels.last() {
                None => check(
                    (crate::exemplar::MIN_EXEMPLAR_SIDE..=crate::exemplar::MAX_EXEMPLAR_SIDE)
                        .contains(&w)
                        && (crate::exemplar::MIN_EXEMPLAR_SIDE
                            ..=crate::exemplar::MAX_EXEMPLAR_SIDE)
                            .contains(&h),
                    || format!("exemplar {e}: size {w}x{h} out of range"),
                )?,
                Some(prev) => check(
                    w == prev.image.width.div_ceil(2) && h == prev.image.height.div_ceil(2),
                    || {
                        format!("exemplar {e} level {level}: size {w}x{h} is not half of the level above")
                    },
                )?,
            }
            if e > 0 {
                let first = &exemplars
                    .first()
                    .map(|x: &ExemplarData| &x.levels[level].image);
                if let Some(f) = first {
                    check((f.width, f.height) == (w, h), || {
                        format!("exemplar {e}: size differs from Ex")
                    })?;
                }
            }
            let n = (w * h) as usize;
            let pixels = r.bytes_padded(n * c as usize)?;
            let image = Image {
                width: w,
                height: h,
                channels: c,
                pixels,
            };
            let (d, k, shift) = (r.u32()?, r.u32()?, r.u32()?);
            check(d == 25 * c && k == params.pca_dims[level], || {
                format!("level {level}: PCA {k} of {d} dims")
            })?;
            let mean: Vec<i32> = r.u32s(d as usize)?.into_iter().map(|v| v as i32).collect();
            let weights: Vec<i32> = r
                .u32s((k * d) as usize)?
                .into_iter()
                .map(|v| v as i32)
                .collect();
            let eigenvalues: Vec<f32> = r
                .u32s(d as usize)?
                .into_iter()
                .map(f32::from_bits)
                .collect();
            let pca = PcaBasis {
                input_dims: d,
                output_dims: k,
                shift,
                mean,
                weights,
                eigenvalues,
            };
            pca.validate().map_err(|m| format!("level {level}: {m}"))?;
            let projected = r.u32s(n * pca.words_per_vector() as usize)?;
            let k2 = params.k2d[level] as usize;
            let candidates_2d = r.u32s(n * k2)?;
            for &c2 in &candidates_2d {
                let (x, y) = unpack(c2);
                check(x < w && y < h, || {
                    format!("level {level}: 2D candidate outside the exemplar")
                })?;
            }
            let owns_3d = e == 0 || !shared;
            let has_3d = r.u32()?;
            check(has_3d == owns_3d as u32, || {
                format!("exemplar {e}: unexpected 3D candidate flag {has_3d}")
            })?;
            let (mut candidates_3d, mut counts_3d, mut slab) = (Vec::new(), Vec::new(), Vec::new());
            if owns_3d {
                let flat = r.u32s(n * k3 * 3)?;
                counts_3d = r.bytes_padded(n)?;
                let slab_flat = r.u32s(n * 3)?;
                for (p, &cnt) in counts_3d.iter().enumerate() {
                    check(cnt as usize <= k3, || {
                        format!("level {level}: {cnt} candidates > {k3}")
                    })?;
                    for j in 0..k3 {
                        let t = &flat[(p * k3 + j) * 3..][..3];
                        let used = j < cnt as usize;
                        for &c3 in t {
                            let (x, y) = unpack(c3);
                            check(if used { x < w && y < h } else { c3 == NO_COORD }, || {
                                format!("level {level}: 3D candidate slot out of range")
                            })?;
                        }
                        // The correction relies on it (it scores that coordinate once).
                        check(!used || t[e] == pack(p as u32 % w, p as u32 / w), || {
                            format!("level {level}: 3D candidate of pixel {p} does not contain it")
                        })?;
                    }
                }
                for &c3 in &slab_flat {
                    let (x, y) = unpack(c3);
                    check(x < w && y < h, || {
                        format!("level {level}: slab coordinate outside")
                    })?;
                }
                candidates_3d = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
                slab = slab_flat
                    .chunks_exact(3)
                    .map(|t| [t[0], t[1], t[2]])
                    .collect();
            }
            let penalty = r.bytes_padded(n)?;
            let stats = LevelStats {
                mean_best_cb: r.f64()?,
                filter_rounds: r.u32()?,
            };
            levels.push(LevelData {
                image,
                pca,
                projected,
                candidates_2d,
                candidates_3d,
                counts_3d,
                slab,
                penalty,
                stats,
            });
        }
        exemplars.push(ExemplarData { levels });
    }
    check(r.at == payload.len(), || {
        format!("{} unexpected trailing bytes", payload.len() - r.at)
    })?;
    Ok(Analysis {
        params,
        border,
        color_channels,
        has_feature,
        shared,
        exemplars,
    })
}
