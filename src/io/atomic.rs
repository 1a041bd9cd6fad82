//! Outputs appear complete or not at all: written to a temporary file beside the target, then
//! renamed over it. An existing directory at the target is refused before any work. A symbolic
//! link is followed (the file it names is replaced, the link kept), and an existing target that
//! is not a regular file (`/dev/null`, a named pipe) is written in place: renaming over it would
//! replace the device or pipe with a file.

use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// The directory an output is staged in: its parent (`.` for a bare file name).
pub fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
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
            if p.is_dir() {
                let _ = std::fs::remove_dir_all(p);
            } else {
                let _ = std::fs::remove_file(p);
            }
        }
    }
}

/// Temporaries beside their targets, named so that they are hidden and recognisable. A
/// temporary is private (0600 / 0700) by default; an output is an ordinary file or directory:
/// `mode` (0666 / 0777) less the user's umask, as any other tool would create it.
fn staging_builder(mode: u32) -> tempfile::Builder<'static, 'static> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(".solidsynth-").suffix(".partial");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(mode));
    }
    #[cfg(not(unix))]
    let _ = mode;
    builder
}

/// Note a temporary for [`discard_pending`].
fn register_pending(tmp: &Path) {
    if let Ok(mut list) = PENDING.lock() {
        list.push(tmp.to_path_buf());
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
#[must_use = "dropping a PendingFile deletes the output: commit it or stage it in Outputs"]
pub struct PendingFile {
    /// The file to replace (a symbolic link's target, resolved).
    path: std::path::PathBuf,
    /// Always Some until committed.
    tmp: Option<tempfile::NamedTempFile>,
    /// Instead of `tmp`: an existing target that is not a regular file, written in place.
    direct: Option<std::fs::File>,
}

impl PendingFile {
    pub fn create(path: &Path) -> Result<PendingFile> {
        // Follow symbolic links: the file they name is the output, and the link stays.
        let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        if std::fs::metadata(&path).is_ok_and(|m| !m.is_file()) {
            // A device or pipe: nothing partial can be left in it, and a rename would replace it.
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(&path)
                .map_err(|e| Error::io(&path, e))?;
            return Ok(PendingFile {
                path,
                tmp: None,
                direct: Some(file),
            });
        }
        let parent = parent_dir(&path);
        let tmp = staging_builder(0o666)
            .tempfile_in(parent)
            .map_err(|e| Error::io(parent, e))?;
        register_pending(tmp.path());
        Ok(PendingFile {
            path,
            tmp: Some(tmp),
            direct: None,
        })
    }

    pub fn file_mut(&mut self) -> &mut std::fs::File {
        match &mut self.direct {
            Some(file) => file,
            None => self.tmp.as_mut().expect("not committed").as_file_mut(),
        }
    }

    /// Append bytes (callers batch them: each call is a system call).
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<()> {
        let path = self.path.clone();
        self.file_mut()
            .write_all(bytes)
            .map_err(|e| Error::io(path, e))
    }

    /// Flush to disk and put the file in place.
    pub fn commit(self) -> Result<()> {
        self.sync()?;
        self.place()?.finish()
    }

    /// Flush the temporary to disk (a device or pipe written in place has nothing to sync).
    fn sync(&self) -> Result<()> {
        if self.direct.is_some() {
            return Ok(());
        }
        let tmp = self.tmp.as_ref().expect("not committed");
        tmp.as_file()
            .sync_all()
            .map_err(|e| Error::io(&self.path, e))
    }

    /// Put the file in place so that [`outputs::Placed`] can take it back: an existing target
    /// is swapped with the temporary, which then holds the former contents.
    fn place(mut self) -> Result<outputs::Placed> {
        use outputs::Placed;
        if self.direct.take().is_some() {
            return Ok(Placed::InPlace);
        }
        let tmp = self.tmp.take().expect("committed once").into_temp_path();
        let path = std::mem::take(&mut self.path);
        let existed = std::fs::symlink_metadata(&path).is_ok();
        if existed {
            match outputs::exchange(&tmp, &path) {
                Ok(true) => return Ok(Placed::Exchanged { path, old: tmp }),
                Ok(false) => {}
                Err(e) => {
                    forget_pending(&tmp);
                    return Err(Error::io(&path, e));
                }
            }
        }
        forget_pending(&tmp);
        tmp.persist(&path).map_err(|e| Error::io(&path, e.error))?;
        Ok(if existed {
            Placed::Replaced(path)
        } else {
            Placed::New(path)
        })
    }
}

/// Directory syncs made (tests: every commit syncs its target's directory).
pub static DIRECTORY_SYNCS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Flush the directory holding `path` to disk, so the rename that put `path` there survives a
/// crash (a file's own sync does not cover its directory entry).
fn sync_parent(path: &Path) -> Result<()> {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    DIRECTORY_SYNCS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    sync_dir(&parent)
}

/// Flush a directory's entries to disk. File systems that cannot sync a directory (some network
/// and FUSE ones) are skipped.
pub fn sync_dir(dir: &Path) -> Result<()> {
    match std::fs::File::open(dir).and_then(|d| d.sync_all()) {
        Ok(()) => Ok(()),
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::InvalidInput | std::io::ErrorKind::Unsupported
            ) =>
        {
            Ok(())
        }
        Err(e) => Err(Error::io(dir, e)),
    }
}

/// A new directory of outputs being filled: a temporary directory beside the target that
/// [`Outputs::commit`] renames into place (the target must not exist, or be an empty
/// directory). Dropped uncommitted, it is deleted with its contents; an interrupt deletes it
/// too (see [`discard_pending`]).
struct PendingDir {
    path: std::path::PathBuf,
    /// Always Some until committed.
    tmp: Option<tempfile::TempDir>,
}

impl PendingDir {
    fn create(path: &Path) -> Result<PendingDir> {
        // A symbolic link to a directory is followed, as for files: the directory it names is
        // the output, and the link stays.
        let resolved = match path.is_symlink() {
            true => std::fs::canonicalize(path).map_err(|e| Error::io(path, e))?,
            false => path.to_path_buf(),
        };
        let path = resolved.as_path();
        let parent = parent_dir(path);
        let tmp = staging_builder(0o777)
            .tempdir_in(parent)
            .map_err(|e| Error::io(parent, e))?;
        register_pending(tmp.path());
        Ok(PendingDir {
            path: path.to_path_buf(),
            tmp: Some(tmp),
        })
    }

    fn staging(&self) -> &Path {
        self.tmp.as_ref().expect("not committed").path()
    }

    /// Flush the files written into the staging directory to disk.
    fn sync(&self) -> Result<()> {
        let dir = self.staging();
        for entry in std::fs::read_dir(dir).map_err(|e| Error::io(&self.path, e))? {
            let entry = entry.map_err(|e| Error::io(&self.path, e))?;
            std::fs::File::open(entry.path())
                .and_then(|f| f.sync_all())
                .map_err(|e| Error::io(&self.path, e))?;
        }
        Ok(())
    }

    /// Rename the staging directory into place (see [`outputs::Placed`]).
    fn place(mut self) -> Result<outputs::Placed> {
        let tmp = self.tmp.take().expect("committed once");
        forget_pending(tmp.path());
        let staged = tmp.keep();
        let over_empty_dir = self.path.is_dir();
        // rename(2) replaces an empty directory; anything else at the target is left as it
        // was, and the staged copy deleted.
        std::fs::rename(&staged, &self.path).map_err(|e| {
            let _ = std::fs::remove_dir_all(&staged);
            Error::io(&self.path, e)
        })?;
        let path = std::mem::take(&mut self.path);
        Ok(if over_empty_dir {
            outputs::Placed::OverEmptyDir(path)
        } else {
            outputs::Placed::New(path)
        })
    }
}

impl Drop for PendingDir {
    fn drop(&mut self) {
        // An uncommitted temporary directory deletes itself (TempDir's drop).
        if let Some(tmp) = &self.tmp {
            forget_pending(tmp.path());
        }
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

/// Save an RGBA image as PNG atomically (RGB when it is opaque: see [`rgba_png_bytes`]).
pub fn save_png(path: &Path, img: &image::RgbaImage) -> Result<()> {
    write_file(path, &rgba_png_bytes(img)?)
}

/// An RGBA picture (a contact sheet, a cut, a render) as PNG, without its alpha channel when
/// every pixel is opaque: a quarter fewer bytes before compression, and the same picture in
/// every viewer.
pub fn rgba_png_bytes(img: &image::RgbaImage) -> Result<Vec<u8>> {
    if img.pixels().all(|p| p.0[3] == 255) {
        png_bytes(&image::DynamicImage::ImageRgba8(img.clone()).to_rgb8())
    } else {
        png_bytes(img)
    }
}

/// An 8-bit image (RGBA, RGB, ...) encoded as PNG, at the encoder's best compression with
/// adaptive filtering (pictures are written once and read or shipped many times).
pub fn png_bytes<P>(img: &image::ImageBuffer<P, Vec<u8>>) -> Result<Vec<u8>>
where
    P: image::Pixel<Subpixel = u8> + image::PixelWithColorType,
{
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let mut buf = Vec::new();
    PngEncoder::new_with_quality(&mut buf, CompressionType::Best, FilterType::Adaptive)
        .write_image(img.as_raw(), img.width(), img.height(), P::COLOR_TYPE)
        .map_err(|e| Error::Internal(format!("PNG encoding failed: {e}")))?;
    Ok(buf)
}

mod checks;
mod outputs;
pub use checks::{
    check_derived_output_path, check_output_dir, check_output_extension, check_output_not_among,
    check_output_outside, check_output_path, check_png_output, set_command_arguments,
};
pub use outputs::Outputs;

#[cfg(test)]
mod tests;
