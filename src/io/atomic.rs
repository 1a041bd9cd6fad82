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

/// Refuse output paths that cannot be a file we write: an existing directory, a missing or
/// unwritable parent, a file the command line names again (an input, or another output: it
/// would be overwritten or written twice).
pub fn check_output_path(path: &Path, flag: &str) -> Result<()> {
    check_file_output(path, flag, 1)
}

/// Refuse an output whose name does not end in one of `extensions` (lower case, without the
/// dot; compared ignoring case), the format the command writes there (`format` names it for the
/// message: "a PNG image"): `cut -o c.nrrd` would otherwise write a PNG under an NRRD's name. An
/// existing device or pipe (`/dev/null`) is taken whatever its name.
pub fn check_output_extension(
    path: &Path,
    flag: &str,
    format: &str,
    extensions: &[&str],
) -> Result<()> {
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
        return Ok(());
    }
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if extension.is_some_and(|e| extensions.contains(&e.as_str())) {
        return Ok(());
    }
    let names: Vec<String> = extensions.iter().map(|e| format!(".{e}")).collect();
    Err(Error::invalid(
        format!("{flag} {}", path.display()),
        format!(
            "is written as {format}: give a name ending in {}",
            names.join(" or ")
        ),
    ))
}

/// [`check_output_path`] and [`check_output_extension`] for a PNG picture.
pub fn check_png_output(path: &Path, flag: &str) -> Result<()> {
    check_output_path(path, flag)?;
    check_output_extension(path, flag, "a PNG image", &["png"])
}

/// [`check_output_path`] for an output the command derives from another one (an OBJ's .mtl
/// and .png): the command line should not name it at all.
pub fn check_derived_output_path(path: &Path, flag: &str) -> Result<()> {
    check_file_output(path, flag, 0)
}

fn check_file_output(path: &Path, flag: &str, own_mentions: usize) -> Result<()> {
    if path.is_dir() {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            "is a directory; give a file path",
        ));
    }
    if path.as_os_str().as_encoded_bytes().ends_with(b"/") {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            "ends in /, which names a directory; give a file path",
        ));
    }
    check_not_reused(path, flag, own_mentions)?;
    check_parent(path, flag)
}

/// The arguments of the command being run (after its program and subcommand names), set by a
/// command-line program with [`set_command_arguments`]; a library caller's process is not
/// read.
static COMMAND_ARGUMENTS: std::sync::OnceLock<Vec<std::ffi::OsString>> = std::sync::OnceLock::new();

/// Register the command's arguments (flags and values, not the program or subcommand names),
/// so that [`check_output_path`] refuses an output the command also names as an input or as
/// another output. Without it that check is skipped.
pub fn set_command_arguments(args: Vec<std::ffi::OsString>) {
    let _ = COMMAND_ARGUMENTS.set(args);
}

/// Refuse an output that the command line names more often than as that output itself: the
/// same file given as an input (`synth ex.png -o ex.png` would replace the exemplar) or as two
/// outputs. Files are compared by their canonical paths (a new file by its directory's).
fn check_not_reused(path: &Path, flag: &str, own_mentions: usize) -> Result<()> {
    let Some(arguments) = COMMAND_ARGUMENTS.get() else {
        return Ok(());
    };
    let Some(key) = file_key(path) else {
        return Ok(());
    };
    let mentions = arguments
        .iter()
        .filter(|arg| {
            // `--flag=PATH` names PATH.
            let text = arg.to_string_lossy();
            let value = match text.split_once('=') {
                Some((name, value)) if name.starts_with("--") => Path::new(value).to_path_buf(),
                _ => Path::new(arg).to_path_buf(),
            };
            file_key(&value).as_ref() == Some(&key)
        })
        .count();
    if mentions > own_mentions {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            "is also given as an input or another output of this command; nothing a command \
             reads is overwritten: choose another output path",
        ));
    }
    Ok(())
}

/// Refuse an output that is one of `inputs`, files a command reads without the command line
/// naming them (a capture directory's images and light file).
pub fn check_output_not_among(
    path: &Path,
    flag: &str,
    inputs: &[std::path::PathBuf],
) -> Result<()> {
    let Some(key) = file_key(path) else {
        return Ok(());
    };
    if let Some(input) = inputs.iter().find(|i| file_key(i).as_ref() == Some(&key)) {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            format!(
                "is {}, which this command reads; nothing a command reads is overwritten: \
                 choose another output path",
                input.display()
            ),
        ));
    }
    Ok(())
}

/// Refuse an output file `path` inside the output directory `dir` (named by `dir_flag`), which
/// the command fills with files of its own.
pub fn check_output_outside(path: &Path, flag: &str, dir: &Path, dir_flag: &str) -> Result<()> {
    let parent = parent_dir(path).canonicalize().ok();
    if parent.is_some() && parent == dir.canonicalize().ok() {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            format!(
                "is inside {dir_flag} {}, which holds that output alone: write it elsewhere",
                dir.display()
            ),
        ));
    }
    Ok(())
}

/// A path's identity: an existing file's device and inode (so that a hard link is the file
/// it links), or else the canonical path of a new file's directory joined with its name; None
/// when neither resolves (not a path of this file system).
fn file_key(path: &Path) -> Option<FileKey> {
    if let Ok(meta) = std::fs::metadata(path) {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            return Some(FileKey::Inode(meta.dev(), meta.ino()));
        }
        #[cfg(not(unix))]
        {
            let _ = meta;
            return path.canonicalize().ok().map(FileKey::Path);
        }
    }
    let name = path.file_name()?;
    Some(FileKey::Path(
        parent_dir(path).canonicalize().ok()?.join(name),
    ))
}

/// What [`file_key`] identifies a file by.
#[derive(Debug, PartialEq, Eq)]
enum FileKey {
    #[cfg_attr(not(unix), allow(dead_code))]
    Inode(u64, u64),
    Path(std::path::PathBuf),
}

/// Refuse an output directory that cannot be one we create: anything but a new or an empty
/// directory at the path (nothing is overwritten), a missing or unwritable parent.
pub fn check_output_dir(path: &Path, flag: &str) -> Result<()> {
    if path.exists() {
        let empty = path.is_dir()
            && std::fs::read_dir(path)
                .map_err(|e| Error::io(path, e))?
                .next()
                .is_none();
        if !empty {
            return Err(Error::invalid(
                format!("{flag} {}", path.display()),
                "exists and is not an empty directory (nothing is overwritten)",
            ));
        }
    }
    check_not_reused(path, flag, 1)?;
    check_parent(path, flag)
}

/// The parent of an output exists and takes new files (where the output is staged: beside the
/// file a symbolic link names). A device or pipe is written in place, not staged (opening a pipe
/// here would wait for its reader).
fn check_parent(path: &Path, flag: &str) -> Result<()> {
    let resolved = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    if std::fs::metadata(&resolved).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    let parent = parent_dir(&resolved);
    if !parent.is_dir() {
        let problem = if parent.exists() {
            format!("{} is a file, not a directory", parent.display())
        } else {
            format!("directory {} does not exist", parent.display())
        };
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            problem,
        ));
    }
    // Outputs are staged beside their target: try that now, before any work, so an
    // unwritable directory is named with its flag rather than found after a long synthesis.
    tempfile::Builder::new()
        .prefix(".solidsynth-")
        .suffix(".probe")
        .tempfile_in(parent)
        .map_err(|e| {
            Error::invalid(
                format!("{flag} {}", path.display()),
                format!("cannot write in directory {}: {e}", parent.display()),
            )
        })?;
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
        self.persist()
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

    /// Rename the temporary over the target.
    fn persist(mut self) -> Result<()> {
        if self.direct.take().is_some() {
            return Ok(());
        }
        let tmp = self.tmp.take().expect("committed once");
        forget_pending(tmp.path());
        tmp.persist(&self.path)
            .map_err(|e| Error::io(&self.path, e.error))?;
        sync_parent(&self.path)
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

mod outputs;
pub use outputs::Outputs;

#[cfg(test)]
mod tests;
