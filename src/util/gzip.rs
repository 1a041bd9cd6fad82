//! One gzip stream read whole, to a limit, and required to end its data: the readers of gzip
//! NRRD volumes and gzip PLY meshes refuse a stream that inflates past what they can hold and
//! bytes after the stream (a second member, trailing garbage), rather than reading whatever
//! comes first.

use std::io::Read;

/// Why a gzip stream was refused.
#[derive(Debug)]
pub enum InflateError {
    /// The stream is not gzip, is cut short, or fails its CRC or length check.
    Damaged(std::io::Error),
    /// It inflates to more than the limit.
    TooLarge,
    /// This many bytes follow the stream.
    Trailing(usize),
}

impl std::fmt::Display for InflateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InflateError::Damaged(e) => write!(
                f,
                "gzip data is damaged ({})",
                crate::error::without_os_code(&e.to_string())
            ),
            InflateError::TooLarge => write!(f, "gzip data inflates past the limit"),
            InflateError::Trailing(n) => write!(f, "{n} bytes follow the gzip data"),
        }
    }
}

/// Inflate the gzip stream `data` (at most `limit` bytes); it must be all of `data`.
pub fn inflate(data: &[u8], limit: u64) -> Result<Vec<u8>, InflateError> {
    let mut decoder = flate2::bufread::GzDecoder::new(data);
    let mut out = Vec::new();
    (&mut decoder)
        .take(limit)
        .read_to_end(&mut out)
        .map_err(|e| match e.kind() {
            // The buffer could not grow: past what this process may allocate.
            std::io::ErrorKind::OutOfMemory => InflateError::TooLarge,
            _ => InflateError::Damaged(e),
        })?;
    // Reading on to the stream's end checks its CRC and length too.
    if decoder
        .read(&mut [0u8; 1])
        .map_err(InflateError::Damaged)?
        > 0
    {
        return Err(InflateError::TooLarge);
    }
    match decoder.into_inner().len() {
        0 => Ok(out),
        after => Err(InflateError::Trailing(after)),
    }
}

/// The first `limit` bytes `data` inflates to, or all of them where the stream ends sooner (what
/// follows is not read, so neither its end nor its checksum is checked): a header read before
/// deciding how far the whole stream may inflate.
pub fn inflate_prefix(data: &[u8], limit: u64) -> Result<Vec<u8>, InflateError> {
    let mut out = Vec::new();
    flate2::bufread::GzDecoder::new(data)
        .take(limit)
        .read_to_end(&mut out)
        .map_err(InflateError::Damaged)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut encoder, data).unwrap();
        encoder.finish().unwrap()
    }

    #[test]
    fn a_stream_is_read_whole_to_its_limit_and_must_end_the_data() {
        let data = gzip(b"hello");
        assert_eq!(inflate(&data, 5).unwrap(), b"hello");
        assert_eq!(inflate(&data, 100).unwrap(), b"hello");
        assert!(matches!(inflate(&data, 4), Err(InflateError::TooLarge)));
        let two_members = [gzip(b"hello"), gzip(b"world")].concat();
        assert!(matches!(
            inflate(&two_members, 100),
            Err(InflateError::Trailing(n)) if n == data.len()
        ));
        let mut damaged = data.clone();
        let crc = damaged.len() - 8;
        damaged[crc] ^= 1;
        assert!(matches!(inflate(&damaged, 100), Err(InflateError::Damaged(_))));
        assert!(matches!(
            inflate(&data[..data.len() - 3], 100),
            Err(InflateError::Damaged(_))
        ));
        assert!(matches!(inflate(b"not gzip", 100), Err(InflateError::Damaged(_))));
    }
}
