//! The HP polynomial texture map file format, version PTM_1.2 (Malzbender and Gelb's
//! "PtmFormat12"), formats `PTM_FORMAT_RGB` and `PTM_FORMAT_LRGB`:
//!
//! ```text
//! PTM_1.2\n
//! PTM_FORMAT_LRGB\n          (or PTM_FORMAT_RGB)
//! <width>\n<height>\n        (whitespace-separated; one line is accepted too)
//! <6 scales>\n               (floats)
//! <6 biases>\n               (integers)
//! <payload>
//! ```
//!
//! Coefficient i stored as byte q means `(q - bias[i]) * scale[i]` (255 = full intensity), in the
//! order a0..a5 of `a0 lu^2 + a1 lv^2 + a2 lu lv + a3 lu + a4 lv + a5`. Rows run bottom to top.
//! LRGB payload: 6 coefficient bytes per pixel for every pixel, then r, g, b per pixel for every
//! pixel. RGB payload: three planes (red, green, blue), each 6 bytes per pixel for every pixel.
//! The reader is strict: the payload must have exactly the announced length.

use super::{Ptm, PtmFormat, COEFFS};

/// Largest side accepted when reading (a bound on what a damaged header can make us allocate,
/// on top of the payload-length check).
pub const MAX_SIDE: u32 = 16_384;

/// Serialize a PTM (byte-exact inverse of [`from_bytes`]).
pub fn to_bytes(ptm: &Ptm) -> Vec<u8> {
    let mut out = Vec::with_capacity(ptm.texels.len() + 128);
    let join = |v: Vec<String>| v.join(" ");
    out.extend_from_slice(
        format!(
            "PTM_1.2\n{}\n{}\n{}\n{}\n{}\n",
            ptm.format.header_name(),
            ptm.width,
            ptm.height,
            // `{}` prints the shortest decimal that reads back to the same f32.
            join(ptm.scale.iter().map(|s| format!("{s}")).collect()),
            join(ptm.bias.iter().map(|b| b.to_string()).collect()),
        )
        .as_bytes(),
    );
    let (w, h) = (ptm.width as usize, ptm.height as usize);
    let s = ptm.format.texel_bytes();
    let rows_bottom_up = |f: &mut dyn FnMut(&[u8])| {
        for y in (0..h).rev() {
            for x in 0..w {
                f(&ptm.texels[(y * w + x) * s..][..s]);
            }
        }
    };
    match ptm.format {
        PtmFormat::Lrgb => {
            rows_bottom_up(&mut |t| out.extend_from_slice(&t[..COEFFS]));
            rows_bottom_up(&mut |t| out.extend_from_slice(&t[COEFFS..COEFFS + 3]));
        }
        PtmFormat::Rgb => {
            for plane in 0..3 {
                rows_bottom_up(&mut |t| {
                    out.extend_from_slice(&t[plane * COEFFS..(plane + 1) * COEFFS])
                });
            }
        }
    }
    out
}

/// Parse a `.ptm` file. Errors say what is wrong (the caller prefixes the path).
pub fn from_bytes(bytes: &[u8]) -> Result<Ptm, String> {
    let mut pos = 0usize;
    let mut line = |what: &str| -> Result<String, String> {
        let rest = &bytes[pos..];
        let end = rest
            .iter()
            .take(64)
            .position(|&b| b == b'\n')
            .ok_or_else(|| format!("not a PTM file: no {what} line"))?;
        pos += end + 1;
        std::str::from_utf8(&rest[..end])
            .map(|s| s.trim_end_matches('\r').to_string())
            .map_err(|_| format!("not a PTM file: {what} is not text"))
    };
    let version = line("version")?;
    if version != "PTM_1.2" {
        return Err(format!(
            "not a PTM_1.2 file (first line {:?})",
            version.chars().take(20).collect::<String>()
        ));
    }
    let format = match line("format")?.trim() {
        "PTM_FORMAT_RGB" => PtmFormat::Rgb,
        "PTM_FORMAT_LRGB" => PtmFormat::Lrgb,
        other => {
            return Err(format!(
                "unsupported PTM format {:?} (only PTM_FORMAT_RGB and PTM_FORMAT_LRGB)",
                other.chars().take(40).collect::<String>()
            ))
        }
    };
    // 14 whitespace-separated tokens: width, height, 6 scales, 6 biases; then the rest of the
    // last token's line (spaces only) and its newline.
    let mut tokens = Vec::with_capacity(14);
    while tokens.len() < 14 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() && pos - start < 32 {
            pos += 1;
        }
        if start == pos || pos >= bytes.len() {
            return Err(format!(
                "truncated header: {} of 14 numbers (width, height, 6 scales, 6 biases)",
                tokens.len()
            ));
        }
        tokens.push(String::from_utf8_lossy(&bytes[start..pos]).to_string());
    }
    while pos < bytes.len() && (bytes[pos] == b' ' || bytes[pos] == b'\t' || bytes[pos] == b'\r') {
        pos += 1;
    }
    if pos >= bytes.len() || bytes[pos] != b'\n' {
        return Err(
            "header: expected 14 numbers (width, height, 6 scales, 6 biases) and then \
                    a newline: a count is missing or extra"
                .into(),
        );
    }
    pos += 1;
    let side = |t: &str, what: &str| -> Result<u32, String> {
        let out_of_range = || {
            let shown = match t.len() > 20 {
                true => format!("{}...", &t[..20]),
                false => t.to_string(),
            };
            format!("header: {what} {shown} is out of range 1..={MAX_SIDE}")
        };
        let v: u64 = match t.parse() {
            Ok(v) => v,
            Err(_) if !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit()) => {
                return Err(out_of_range())
            }
            Err(_) => return Err(format!("header: {what} {t:?} is not a whole number")),
        };
        if v == 0 || v > MAX_SIDE as u64 {
            return Err(out_of_range());
        }
        Ok(v as u32)
    };
    let width = side(&tokens[0], "width")?;
    let height = side(&tokens[1], "height")?;
    let mut scale = [0f32; COEFFS];
    let mut bias = [0i32; COEFFS];
    for i in 0..COEFFS {
        let t = &tokens[2 + i];
        scale[i] = t
            .parse::<f32>()
            .ok()
            .filter(|s| s.is_finite())
            .ok_or_else(|| {
                format!("header: scale {i} {t:?} is not a number within a 32-bit float's range")
            })?;
        let t = &tokens[8 + i];
        bias[i] = t
            .parse::<i32>()
            .ok()
            .filter(|b| b.abs() <= 1 << 20)
            .ok_or_else(|| format!("header: bias {i} {t:?} is not an integer in range"))?;
    }
    let (w, h) = (width as usize, height as usize);
    let s = format.texel_bytes();
    let expected = w * h * s;
    let payload = &bytes[pos..];
    if payload.len() < expected {
        return Err(format!(
            "truncated: {width}x{height} {} needs {expected} payload bytes, file has {}",
            format.header_name(),
            payload.len()
        ));
    }
    if payload.len() > expected {
        return Err(format!(
            "{} unexpected bytes after the {expected}-byte payload",
            payload.len() - expected
        ));
    }
    let mut texels = vec![0u8; expected];
    let mut src = payload.chunks_exact(1);
    let mut next = || src.next().unwrap()[0];
    let mut fill = |offset: usize, count: usize| {
        for y in (0..h).rev() {
            for x in 0..w {
                for k in 0..count {
                    texels[(y * w + x) * s + offset + k] = next();
                }
            }
        }
    };
    match format {
        PtmFormat::Lrgb => {
            fill(0, COEFFS);
            fill(COEFFS, 3);
        }
        PtmFormat::Rgb => {
            for plane in 0..3 {
                fill(plane * COEFFS, COEFFS);
            }
        }
    }
    Ok(Ptm {
        format,
        width,
        height,
        scale,
        bias,
        texels,
    })
}

/// Read a `.ptm` file; damage is a [`crate::Error::CorruptFile`] naming the path.
pub fn load(path: &std::path::Path) -> crate::Result<Ptm> {
    let bytes = crate::io::input::read(path)?;
    from_bytes(&bytes).map_err(|p| crate::Error::corrupt(path, p))
}

/// Write a `.ptm` file atomically.
pub fn save(path: &std::path::Path, ptm: &Ptm) -> crate::Result<()> {
    ptm.check("PTM")?;
    crate::io::atomic::write_file(path, &to_bytes(ptm))
}
