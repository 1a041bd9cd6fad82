//! NRRD volumes: 8-bit, 1 to 4 channels, raw or gzip encoding, data attached to the header.
//!
//! Written as `NRRD0004`, `type: uint8`, `dimension: 4`, `sizes: C X Y Z`, `encoding: raw` (or
//! `gzip`, what 3D Slicer writes by default), x fastest after the channel. Read: versions NRRD0001-0005, types uint8/uchar/unsigned char,
//! dimension 3 (one channel, `sizes: X Y Z`) or 4 (`sizes: C X Y Z`, C = 1..=4), encodings raw and
//! gzip; header fields we do not need are skipped, detached data files are refused.

use crate::error::{Error, Result};
use crate::volume::Volume;
use std::path::Path;

/// Largest volume accepted when reading (voxels x channels), to refuse absurd headers before
/// allocating.
pub const MAX_READ_BYTES: u64 = 8 << 30;

/// The header text of a volume.
pub fn header(v: &Volume) -> String {
    header_of(v.dims(), v.channels)
}

/// The header text of a volume of `dims` voxels with `channels` bytes each, raw.
pub fn header_of(dims: [u32; 3], channels: u32) -> String {
    header_encoded(dims, channels, false)
}

/// The header text of a volume of `dims` voxels with `channels` bytes each, its data raw or
/// gzip-compressed.
pub fn header_encoded(dims: [u32; 3], channels: u32, gzip: bool) -> String {
    let kind = match channels {
        3 => "RGB-color",
        4 => "RGBA-color",
        _ => "vector",
    };
    format!(
        "NRRD0004\n# written by solidsynth\ntype: uint8\ndimension: 4\nsizes: {} {} {} {}\n\
         kinds: {kind} domain domain domain\nencoding: {}\n\n",
        channels,
        dims[0],
        dims[1],
        dims[2],
        if gzip { "gzip" } else { "raw" }
    )
}

/// Write a volume atomically.
pub fn save(v: &Volume, path: &Path) -> Result<()> {
    let mut w = SlabWriter::create(path, v.dims(), v.channels)?;
    w.write_slab(v)?;
    w.finish()?.commit()
}

/// A volume written slab by slab along z (the file's order), so a large synthesis need not
/// hold it whole. Atomic: nothing appears at the path until [`SlabWriter::finish`], which
/// checks that every slice arrived; dropped before, the partial file is deleted.
pub struct SlabWriter {
    file: crate::io::atomic::PendingFile,
    order: crate::io::slab_order::SlabOrder,
    /// gzip encoding: the compressor, whose output so far is moved to the file after each slab
    /// (so memory stays one slab's, as with raw data).
    gzip: Option<flate2::write::GzEncoder<Vec<u8>>>,
}

impl SlabWriter {
    /// A raw NRRD file.
    pub fn create(path: &Path, dims: [u32; 3], channels: u32) -> Result<SlabWriter> {
        SlabWriter::create_encoded(path, dims, channels, false)
    }

    /// A NRRD file, its data raw or gzip-compressed.
    pub fn create_encoded(
        path: &Path,
        dims: [u32; 3],
        channels: u32,
        gzip: bool,
    ) -> Result<SlabWriter> {
        let mut file = crate::io::atomic::PendingFile::create(path)?;
        file.write_all(header_encoded(dims, channels, gzip).as_bytes())?;
        Ok(SlabWriter {
            file,
            order: crate::io::slab_order::SlabOrder::new(dims, channels)?,
            gzip: gzip
                .then(|| flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default())),
        })
    }

    /// The next `slab.nz` z slices (x and y extents and channels those of the volume).
    pub fn write_slab(&mut self, slab: &Volume) -> Result<()> {
        self.order.advance(slab)?;
        match &mut self.gzip {
            None => self.file.write_all(&slab.data),
            Some(encoder) => {
                use std::io::Write;
                encoder
                    .write_all(&slab.data)
                    .expect("compressing into memory cannot fail");
                let compressed = std::mem::take(encoder.get_mut());
                self.file.write_all(&compressed)
            }
        }
    }

    /// The complete file, to commit or to stage with a command's other outputs
    /// ([`crate::io::atomic::Outputs`]).
    pub fn finish(mut self) -> Result<crate::io::atomic::PendingFile> {
        self.order.finish()?;
        if let Some(encoder) = self.gzip.take() {
            let tail = encoder
                .finish()
                .expect("compressing into memory cannot fail");
            self.file.write_all(&tail)?;
        }
        Ok(self.file)
    }
}

/// The gzip stream of `data` (default level), for a gzip-encoded NRRD held in memory.
pub fn gzip_bytes(data: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder
        .write_all(data)
        .expect("compressing into memory cannot fail");
    encoder
        .finish()
        .expect("compressing into memory cannot fail")
}

/// Read a volume file. A volume larger than the memory available (the machine's, its cgroup's
/// and `ulimit -v`'s room, or `SOLIDSYNTH_MEMORY_BUDGET_MIB`) is refused before its data is
/// decoded.
pub fn load(path: &Path) -> Result<Volume> {
    let bytes = crate::io::input::read(path)?;
    let header = parse_header(&bytes).map_err(|problem| Error::corrupt(path, problem))?;
    let available = crate::util::memory::available_memory();
    if header.bytes > available {
        return Err(Error::invalid(
            path.display().to_string(),
            format!(
                "holds a {}x{}x{} volume of {}, more memory than there is: {}",
                header.dims[0],
                header.dims[1],
                header.dims[2],
                crate::util::memory::human_bytes(header.bytes),
                crate::util::memory::available_text(available)
            ),
        ));
    }
    decode(&bytes, header).map_err(|problem| Error::corrupt(path, problem))
}

/// What a NRRD header says about its volume, and where its data starts.
#[derive(Clone, Copy, Debug)]
struct Header {
    dims: [u64; 3],
    channels: u64,
    /// The data's size decoded (channels x voxels).
    bytes: u64,
    gzip: bool,
    data_start: usize,
}

/// Parse NRRD bytes; the error says what is wrong.
pub fn parse(bytes: &[u8]) -> std::result::Result<Volume, String> {
    let header = parse_header(bytes)?;
    decode(bytes, header)
}

/// The header of NRRD bytes, checked.
fn parse_header(bytes: &[u8]) -> std::result::Result<Header, String> {
    if !bytes.starts_with(b"NRRD000") || bytes.len() < 9 || !(b'1'..=b'5').contains(&bytes[7]) {
        return Err("not an NRRD file (expected magic NRRD0001..NRRD0005)".into());
    }
    // The header ends at the first empty line (its lines end in LF, or CRLF where a Windows
    // tool wrote it).
    let (end, blank) = (0..bytes.len())
        .find_map(|i| match &bytes[i..] {
            [b'\n', b'\n', ..] => Some((i, 2)),
            [b'\n', b'\r', b'\n', ..] => Some((i, 3)),
            _ => None,
        })
        .ok_or("no end of header (blank line) found")?;
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| "header is not text")?;
    let (mut ty, mut dimension, mut sizes, mut encoding) = (None, None, None, None);
    for line in text.lines().skip(1) {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            continue; // key:=value pairs and unknown syntax are not ours to interpret
        };
        let value = value.trim_start_matches('=').trim();
        match key.trim() {
            "type" => ty = Some(value.to_string()),
            "dimension" => {
                dimension = Some(
                    value
                        .parse::<u32>()
                        .map_err(|_| format!("bad dimension '{value}'"))?,
                )
            }
            "sizes" => {
                sizes = Some(
                    value
                        .split_whitespace()
                        .map(|s| s.parse::<u64>().map_err(|_| format!("bad size '{s}'")))
                        .collect::<std::result::Result<Vec<_>, _>>()?,
                )
            }
            "encoding" => encoding = Some(value.to_string()),
            "data file" | "datafile" => return Err("detached data files are not supported".into()),
            _ => {}
        }
    }
    let ty = ty.ok_or("missing 'type'")?;
    if !matches!(ty.as_str(), "uint8" | "uchar" | "unsigned char" | "uint8_t") {
        return Err(format!("type '{ty}' is not supported (only uint8)"));
    }
    let dimension = dimension.ok_or("missing 'dimension'")?;
    let sizes = sizes.ok_or("missing 'sizes'")?;
    if sizes.len() != dimension as usize {
        return Err(format!("{} sizes for dimension {dimension}", sizes.len()));
    }
    let (c, x, y, z) = match sizes.as_slice() {
        [x, y, z] => (1, *x, *y, *z),
        [c, x, y, z] => (*c, *x, *y, *z),
        _ => return Err(format!("dimension {dimension} is not supported (3 or 4)")),
    };
    if !(1..=4).contains(&c) {
        return Err(format!(
            "{c} channels (the first size) is not supported (1 to 4)"
        ));
    }
    if x == 0
        || y == 0
        || z == 0
        || x > u32::MAX as u64
        || y > u32::MAX as u64
        || z > u32::MAX as u64
    {
        return Err(format!("bad volume size {x}x{y}x{z}"));
    }
    let want = c
        .checked_mul(x)
        .and_then(|v| v.checked_mul(y))
        .and_then(|v| v.checked_mul(z))
        .ok_or("size overflow")?;
    if want > MAX_READ_BYTES {
        return Err(format!(
            "volume of {want} bytes is larger than the {MAX_READ_BYTES}-byte limit"
        ));
    }
    let gzip = match encoding.as_deref().ok_or("missing 'encoding'")? {
        "raw" => false,
        "gzip" | "gz" => true,
        other => return Err(format!("encoding '{other}' is not supported (raw or gzip)")),
    };
    Ok(Header {
        dims: [x, y, z],
        channels: c,
        bytes: want,
        gzip,
        data_start: end + blank,
    })
}

/// The volume of `bytes` whose header is `header`.
fn decode(bytes: &[u8], header: Header) -> std::result::Result<Volume, String> {
    let data = &bytes[header.data_start..];
    let want = header.bytes;
    let ([x, y, z], c) = (header.dims, header.channels);
    let raw: Vec<u8> = if header.gzip {
        inflate(data, want).map_err(|problem| format!("{problem}: sizes {c} {x} {y} {z}"))?
    } else {
        data.to_vec()
    };
    if raw.len() as u64 != want {
        return Err(format!(
            "data is {} bytes but sizes {c} {x} {y} {z} need {want}",
            raw.len()
        ));
    }
    Ok(Volume {
        nx: x as u32,
        ny: y as u32,
        nz: z as u32,
        channels: c as u32,
        data: raw,
    })
}

/// The `want` bytes of the gzip stream `data`, which must end the file: a stream that
/// inflates to more or less, or is followed by other bytes, is refused (the message says which;
/// the caller appends the sizes).
fn inflate(data: &[u8], want: u64) -> std::result::Result<Vec<u8>, String> {
    use crate::util::gzip::{self, InflateError};
    let out = gzip::inflate(data, want).map_err(|e| match e {
        InflateError::TooLarge => format!("gzip data inflates to more than the {want} bytes"),
        InflateError::Trailing(after) => {
            format!("{after} bytes follow the gzip data, which holds the {want} bytes")
        }
        damaged => damaged.to_string(),
    })?;
    if (out.len() as u64) < want {
        return Err(format!(
            "gzip data inflates to {} bytes, fewer than the {want}",
            out.len()
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Volume {
        let mut v = Volume::new(3, 4, 5, 3);
        v.data
            .iter_mut()
            .enumerate()
            .for_each(|(i, b)| *b = (i * 7 % 256) as u8);
        v
    }

    #[test]
    fn crlf_headers_read_like_lf_ones() {
        let v = Volume {
            nx: 2,
            ny: 1,
            nz: 1,
            channels: 1,
            data: vec![7, 9],
        };
        let text = header(&v).replace('\n', "\r\n");
        let mut bytes = text.into_bytes();
        bytes.extend(&v.data);
        assert_eq!(parse(&bytes).unwrap(), v);
    }

    #[test]
    fn round_trip_raw_and_gzip() {
        let v = sample();
        let mut bytes = header(&v).into_bytes();
        bytes.extend_from_slice(&v.data);
        assert_eq!(parse(&bytes).unwrap(), v);

        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut gz, &v.data).unwrap();
        let text = header(&v).replace("encoding: raw", "encoding: gzip");
        let mut bytes = text.into_bytes();
        bytes.extend_from_slice(&gz.finish().unwrap());
        assert_eq!(parse(&bytes).unwrap(), v);

        // Three-dimensional (one channel) form.
        let mut bytes =
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n".to_vec();
        bytes.extend_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8]);
        let g = parse(&bytes).unwrap();
        assert_eq!((g.channels, g.nx, g.ny, g.nz), (1, 2, 2, 2));
    }

    #[test]
    fn gzip_data_must_hold_the_volume_and_end_the_file() {
        let v = sample();
        let text = header(&v).replace("encoding: raw", "encoding: gzip");
        let file = |data: &[u8], tail: &[u8]| {
            let mut bytes = text.clone().into_bytes();
            bytes.extend_from_slice(&gzip_bytes(data));
            bytes.extend_from_slice(tail);
            parse(&bytes)
        };
        assert_eq!(file(&v.data, b"").unwrap(), v);
        let e = file(&v.data, b"junk").unwrap_err();
        assert!(e.contains("4 bytes follow the gzip data"), "{e}");
        let e = file(&v.data[1..], b"").unwrap_err();
        assert!(
            e.contains("inflates to 179 bytes, fewer than the 180"),
            "{e}"
        );
        let e = file(&[v.data.clone(), vec![0; 4096]].concat(), b"").unwrap_err();
        assert!(e.contains("inflates to more than the 180 bytes"), "{e}");
        assert!(e.contains("sizes 3 3 4 5"), "{e}");
        let mut damaged = gzip_bytes(&v.data);
        let crc = damaged.len() - 8;
        damaged[crc] ^= 1;
        let mut bytes = text.clone().into_bytes();
        bytes.extend_from_slice(&damaged);
        let e = parse(&bytes).unwrap_err();
        assert!(e.contains("damaged"), "{e}");
    }

    #[test]
    fn bad_headers_are_named() {
        let v = sample();
        let mut ok = header(&v).into_bytes();
        ok.extend_from_slice(&v.data);
        let t = |s: &str| {
            let mut b = s.as_bytes().to_vec();
            b.extend_from_slice(&v.data);
            parse(&b).unwrap_err()
        };
        assert!(parse(b"hello").unwrap_err().contains("magic"));
        assert!(t(&header(&v).replace("uint8", "float")).contains("float"));
        assert!(t(&header(&v).replace("sizes: 3 3 4 5", "sizes: 3 3 4 6")).contains("need"));
        assert!(t(&header(&v).replace("sizes: 3 3 4 5", "sizes: 7 3 4 5")).contains("channels"));
        assert!(t(&header(&v).replace("raw", "bzip2")).contains("bzip2"));
        assert!(parse(&ok[..ok.len() - 1]).unwrap_err().contains("need"));
    }

    #[test]
    fn fuzz_never_panics() {
        let v = sample();
        let mut ok = header(&v).into_bytes();
        ok.extend_from_slice(&v.data);
        let mut rng = crate::util::hash::SeededRng::new(1);
        for _ in 0..3000 {
            let mut b = ok.clone();
            for _ in 0..1 + rng.below(3) {
                if b.is_empty() {
                    break;
                }
                let at = rng.below(b.len() as u64) as usize;
                match rng.below(3) {
                    0 => b[at] = rng.below(256) as u8,
                    1 => b.truncate(at),
                    _ => b.insert(at, b"0123456789 \n:"[rng.below(13) as usize]),
                }
            }
            let _ = parse(&b);
        }
    }
}
