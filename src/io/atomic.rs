//! Outputs appear complete or not at all: written to a temporary file beside the target, then
//! renamed over it. An existing directory at the target is refused before any work.

use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// Refuse output paths that cannot be a file we write: an existing directory, a missing parent.
pub fn check_output_path(path: &Path, flag: &str) -> Result<()> {
    if path.is_dir() {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            "is a directory; give a file path",
        ));
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            format!("directory {} does not exist", parent.display()),
        ));
    }
    Ok(())
}

/// Write `bytes` to `path` atomically.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with(path, |f| f.write_all(bytes))
}

/// Write to `path` atomically through `fill`.
pub fn write_with(
    path: &Path,
    fill: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> Result<()> {
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut tmp = tempfile::Builder::new()
        .prefix(".solidsynth-")
        .suffix(".partial")
        .tempfile_in(parent)
        .map_err(|e| Error::io(parent, e))?;
    fill(tmp.as_file_mut()).map_err(|e| Error::io(path, e))?;
    tmp.as_file().sync_all().map_err(|e| Error::io(path, e))?;
    tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    Ok(())
}

/// Save an RGBA image as PNG atomically.
pub fn save_png(path: &Path, img: &image::RgbaImage) -> Result<()> {
    write_file(path, &png_bytes(img)?)
}

/// An RGBA image encoded as PNG.
pub fn png_bytes(img: &image::RgbaImage) -> Result<Vec<u8>> {
    let mut buf = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut buf), image::ImageFormat::Png)
        .map_err(|e| Error::Gpu(format!("PNG encoding failed: {e}")))?;
    Ok(buf)
}
