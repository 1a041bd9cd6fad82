//! VTK image data (`.vti`, XML, ParaView's native volume format) for solid volumes: one point
//! array "color" of `channels` UInt8 components, stored raw in the appended section (a UInt32
//! byte count, then the bytes, x fastest), so files stay as compact as the NRRD.

use super::atomic;
use crate::error::{Error, Result};
use crate::volume::Volume;
use std::path::Path;

fn header(v: &Volume) -> String {
    let extent = format!("0 {} 0 {} 0 {}", v.nx - 1, v.ny - 1, v.nz - 1);
    format!(
        "<?xml version=\"1.0\"?>\n\
         <VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\">\n\
         <ImageData WholeExtent=\"{extent}\" Origin=\"0 0 0\" Spacing=\"1 1 1\">\n\
         <Piece Extent=\"{extent}\">\n\
         <PointData Scalars=\"color\">\n\
         <DataArray type=\"UInt8\" Name=\"color\" NumberOfComponents=\"{}\" format=\"appended\" offset=\"0\"/>\n\
         </PointData>\n\
         </Piece>\n\
         </ImageData>\n\
         <AppendedData encoding=\"raw\">\n_",
        v.channels
    )
}

/// The .vti bytes of a volume; an error for a volume with a zero side, other than 1 to 4
/// channels, data that does not match its sizes, or over 4 GiB of data.
pub fn to_bytes(v: &Volume) -> Result<Vec<u8>> {
    to_checked_bytes(v, Path::new("volume"))
}

fn encode(v: &Volume) -> Vec<u8> {
    let mut out = header(v).into_bytes();
    out.extend((v.data.len() as u32).to_le_bytes());
    out.extend_from_slice(&v.data);
    out.extend_from_slice(b"\n</AppendedData>\n</VTKFile>\n");
    out
}

pub fn save(v: &Volume, path: &Path) -> Result<()> {
    atomic::write_file(path, &to_checked_bytes(v, path)?)
}

/// [`to_bytes`], its errors naming `path` (the output) for a volume the format cannot hold.
pub fn to_checked_bytes(v: &Volume, path: &Path) -> Result<Vec<u8>> {
    crate::io::slab_order::check_dims(v.dims(), v.channels)?;
    v.check("volume")?;
    if v.data.len() > u32::MAX as usize {
        return Err(Error::invalid(
            path.display().to_string(),
            "a volume over 4 GiB does not fit a UInt32-headed .vti",
        ));
    }
    Ok(encode(v))
}

/// Read back a .vti written by [`to_bytes`] (this layout only: tests and round trips).
pub fn from_bytes(bytes: &[u8], name: &str) -> Result<Volume> {
    let bad = |why: &str| Error::invalid(name, why.to_string());
    let marker = b"<AppendedData encoding=\"raw\">\n_";
    let at = bytes
        .windows(marker.len())
        .position(|w| w == marker)
        .ok_or_else(|| bad("no raw appended data"))?;
    let text = std::str::from_utf8(&bytes[..at]).map_err(|_| bad("header is not text"))?;
    let attr = |key: &str| -> Option<&str> {
        let i = text.find(&format!("{key}=\""))? + key.len() + 2;
        Some(&text[i..i + text[i..].find('"')?])
    };
    let extent: Vec<u32> = attr("WholeExtent")
        .ok_or_else(|| bad("no WholeExtent"))?
        .split_whitespace()
        .map(|t| t.parse::<u32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| bad("bad WholeExtent"))?;
    let channels: u32 = attr("NumberOfComponents")
        .and_then(|c| c.parse().ok())
        .ok_or_else(|| bad("no NumberOfComponents"))?;
    if extent.len() != 6
        || extent[0] != 0
        || extent[2] != 0
        || extent[4] != 0
        || !(1..=4).contains(&channels)
    {
        return Err(bad("unsupported extent or components"));
    }
    let (nx, ny, nz) = (extent[1] + 1, extent[3] + 1, extent[5] + 1);
    let start = at + marker.len();
    let len = bytes
        .get(start..start + 4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()) as usize)
        .ok_or_else(|| bad("truncated"))?;
    let expected = nx as usize * ny as usize * nz as usize * channels as usize;
    if len != expected || bytes.len() < start + 4 + len {
        return Err(bad("data size does not match the extent"));
    }
    let mut v = Volume::new(nx, ny, nz, channels);
    v.data.copy_from_slice(&bytes[start + 4..start + 4 + len]);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_refuses_damage() {
        let mut v = Volume::new(5, 3, 4, 3);
        for (i, b) in v.data.iter_mut().enumerate() {
            *b = (i * 7 % 251) as u8;
        }
        let bytes = to_bytes(&v).unwrap();
        assert_eq!(from_bytes(&bytes, "t").unwrap(), v);
        assert!(from_bytes(&bytes[..bytes.len() / 2], "t").is_err());
        let text = String::from_utf8_lossy(&bytes[..200]).to_string();
        assert!(text.contains("WholeExtent=\"0 4 0 2 0 3\""));
    }
}
