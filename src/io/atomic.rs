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
    let mut pending = PendingFile::create(path)?;
    fill(pending.file_mut()).map_err(|e| Error::io(path, e))?;
    pending.commit()
}

/// Temporaries of the outputs being written, for [`discard_pending`].
static PENDING: std::sync::Mutex<Vec<std::path::PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Delete the temporaries of the outputs still being written: for an interrupt handler (the
/// process is about to exit, so nothing will commit them, and a long synthesis streams its
/// volume into one for minutes).
pub fn discard_pending() {
    if let Ok(list) = PENDING.lock() {
        for p in list.iter() {
            let _ = std::fs::remove_file(p);
        }
    }
}

fn forget_pending(tmp: &Path) {
    if let Ok(mut list) = PENDING.lock() {
        list.retain(|p| p != tmp);
    }
}

/// An output being written piece by piece (a volume streamed slab by slab): a temporary file
/// beside the target that [`PendingFile::commit`] renames over it. Dropped uncommitted (an
/// error on the way), the temporary is deleted and the target left as it was; an interrupt
/// deletes it too (see [`discard_pending`]).
pub struct PendingFile {
    path: std::path::PathBuf,
    /// Always Some until committed.
    tmp: Option<tempfile::NamedTempFile>,
}

impl PendingFile {
    pub fn create(path: &Path) -> Result<PendingFile> {
        let parent = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let mut builder = tempfile::Builder::new();
        builder.prefix(".solidsynth-").suffix(".partial");
        // A temporary file is private (0600) by default; an output is an ordinary file: 0666
        // less the user's umask, as any other tool would create it.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let tmp = builder
            .tempfile_in(parent)
            .map_err(|e| Error::io(parent, e))?;
        if let Ok(mut list) = PENDING.lock() {
            list.push(tmp.path().to_path_buf());
        }
        Ok(PendingFile {
            path: path.to_path_buf(),
            tmp: Some(tmp),
        })
    }

    pub fn file_mut(&mut self) -> &mut std::fs::File {
        self.tmp.as_mut().expect("not committed").as_file_mut()
    }

    /// Append bytes (callers batch them: each call is a system call).
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<()> {
        let path = self.path.clone();
        self.file_mut()
            .write_all(bytes)
            .map_err(|e| Error::io(path, e))
    }

    /// Flush to disk and put the file in place.
    pub fn commit(mut self) -> Result<()> {
        let tmp = self.tmp.take().expect("committed once");
        forget_pending(tmp.path());
        tmp.as_file()
            .sync_all()
            .map_err(|e| Error::io(&self.path, e))?;
        tmp.persist(&self.path)
            .map_err(|e| Error::io(&self.path, e.error))?;
        Ok(())
    }
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        // An uncommitted temporary deletes itself (NamedTempFile's drop).
        if let Some(tmp) = &self.tmp {
            forget_pending(tmp.path());
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[cfg(unix)]
    fn outputs_are_ordinary_files_not_private_temporaries() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        write_file(&path, b"abc").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"abc");
        // Readable by the group and others unless the umask forbids it (the usual 022 or 002
        // does not); the temporary's 0600 would fail this.
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o600, 0o600, "{mode:o}");
        assert_ne!(mode & 0o044, 0, "{mode:o}");
        // No temporary left beside it.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn an_uncommitted_output_leaves_the_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bin");
        std::fs::write(&path, b"old").unwrap();
        let mut pending = PendingFile::create(&path).unwrap();
        pending.write_all(b"new, half written").unwrap();
        drop(pending);
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let mut pending = PendingFile::create(&path).unwrap();
        pending.write_all(b"new").unwrap();
        pending.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
