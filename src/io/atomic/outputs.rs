//! A command's outputs put in place together, and taken back together when one of them cannot
//! be: a later output that cannot replace its target (an immutable file, a full directory)
//! leaves the earlier ones' targets as they were, not some of them new.

use super::{rgba_png_bytes, sync_parent, PendingDir, PendingFile};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The outputs of one command, each staged as a temporary beside its target and all put in
/// place together by [`Outputs::commit`] once every one is complete: a command that fails or is
/// interrupted on the way (a later output's error, a full disk) leaves none of them behind, not
/// merely no half-written one.
#[derive(Default)]
pub struct Outputs {
    files: Vec<PendingFile>,
    dirs: Vec<PendingDir>,
}

impl Outputs {
    pub fn new() -> Outputs {
        Outputs::default()
    }

    /// Add a file written piece by piece (complete when staged).
    pub fn stage(&mut self, file: PendingFile) {
        self.files.push(file);
    }

    /// Stage `bytes` as the file `path`.
    pub fn write_file(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        let mut file = PendingFile::create(path)?;
        file.write_all(bytes)?;
        self.stage(file);
        Ok(())
    }

    /// Stage an RGBA image as the PNG file `path` (RGB when it is opaque: see [`rgba_png_bytes`]).
    pub fn save_png(&mut self, path: &Path, img: &image::RgbaImage) -> Result<()> {
        self.write_file(path, &rgba_png_bytes(img)?)
    }

    /// Stage a new directory `path`: returns the temporary directory to fill in its place.
    pub fn directory(&mut self, path: &Path) -> Result<PathBuf> {
        let dir = PendingDir::create(path)?;
        let staging = dir.staging().to_path_buf();
        self.dirs.push(dir);
        Ok(staging)
    }

    /// Flush everything staged to disk, then put each in place: directories first (their
    /// rename is the one most often refused: the target was given files meanwhile), then the
    /// files, each existing target swapped with its replacement (`renameat2`'s exchange) so that
    /// its old contents stay at hand. When one cannot be put in place, those already placed are
    /// swapped back or removed, and the error names the output that failed. Only then are the
    /// old contents deleted. (On a file system without the exchange, a replaced file cannot be
    /// restored; and an interrupt between the renames, a window of microseconds, can still leave
    /// some in place.)
    pub fn commit(self) -> Result<()> {
        for f in &self.files {
            f.sync()?;
        }
        for d in &self.dirs {
            d.sync()?;
        }
        let mut placed = Vec::new();
        for d in self.dirs {
            match d.place() {
                Ok(p) => placed.push(p),
                Err(e) => return Err(undo(placed, e)),
            }
        }
        for f in self.files {
            match f.place() {
                Ok(p) => placed.push(p),
                Err(e) => return Err(undo(placed, e)),
            }
        }
        for p in placed {
            p.finish()?;
        }
        Ok(())
    }
}

/// Take back what `placed` put in place, newest first; returns `error`.
fn undo(placed: Vec<Placed>, error: Error) -> Error {
    for p in placed.into_iter().rev() {
        p.undo();
    }
    error
}

/// An output put in place, with what undoing it takes.
pub(super) enum Placed {
    /// A device or pipe, written in place as the command ran.
    InPlace,
    /// A new file or directory where there was none.
    New(PathBuf),
    /// A directory renamed over an empty one, which undoing makes again.
    OverEmptyDir(PathBuf),
    /// A file swapped with its target: `old` (deleted when dropped) holds the target's former
    /// contents.
    Exchanged {
        path: PathBuf,
        old: tempfile::TempPath,
    },
    /// A file renamed over its target on a file system without the exchange: no way back.
    Replaced(PathBuf),
}

impl Placed {
    fn undo(self) {
        match self {
            Placed::New(path) => {
                let _ = std::fs::remove_file(&path).or_else(|_| std::fs::remove_dir_all(&path));
            }
            Placed::OverEmptyDir(path) => {
                if std::fs::remove_dir_all(&path).is_ok() {
                    let _ = std::fs::create_dir(&path);
                }
            }
            Placed::Exchanged { path, old } => {
                // Swapped back, `old` holds the new contents, deleted as it drops.
                let _ = exchange(&old, &path);
                super::forget_pending(&old);
            }
            Placed::InPlace | Placed::Replaced(_) => {}
        }
    }

    /// Make the placement durable (its directory synced) and delete the former contents.
    pub(super) fn finish(self) -> Result<()> {
        match self {
            Placed::InPlace => Ok(()),
            Placed::New(path) | Placed::OverEmptyDir(path) | Placed::Replaced(path) => {
                sync_parent(&path)
            }
            Placed::Exchanged { path, old } => {
                super::forget_pending(&old);
                drop(old);
                sync_parent(&path)
            }
        }
    }
}

/// Swap the files at `a` and `b` atomically. Ok(false) where the system or file system has no
/// such exchange (then nothing happened).
pub(super) fn exchange(a: &Path, b: &Path) -> std::io::Result<bool> {
    #[cfg(all(target_os = "linux", any(target_env = "gnu", target_env = "musl")))]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = |p: &Path| {
            std::ffi::CString::new(p.as_os_str().as_bytes())
                .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))
        };
        let (a, b) = (c(a)?, c(b)?);
        // SAFETY: renameat2 reads the two NUL-terminated paths; AT_FDCWD resolves them as
        // open(2) would.
        let status = unsafe {
            libc::renameat2(
                libc::AT_FDCWD,
                a.as_ptr(),
                libc::AT_FDCWD,
                b.as_ptr(),
                libc::RENAME_EXCHANGE,
            )
        };
        if status == 0 {
            return Ok(true);
        }
        let error = std::io::Error::last_os_error();
        match error.raw_os_error() {
            Some(libc::EINVAL) | Some(libc::ENOSYS) | Some(libc::EOPNOTSUPP) => Ok(false),
            _ => Err(error),
        }
    }
    #[cfg(not(all(target_os = "linux", any(target_env = "gnu", target_env = "musl"))))]
    {
        let _ = (a, b);
        Ok(false)
    }
}
