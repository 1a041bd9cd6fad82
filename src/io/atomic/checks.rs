//! The checks every output path passes before any work: not a directory, not an input or
//! another output of the command, in a directory that exists and takes new files, named with its
//! format's extension, not standard output beside a `--json` summary.

use super::parent_dir;
use crate::error::{Error, Result};
use std::path::Path;

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
    #[cfg(unix)]
    if std::fs::metadata(path).is_err_and(|e| e.raw_os_error() == Some(libc::ELOOP)) {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            "is a symbolic link that leads back to itself: give a file path",
        ));
    }
    if path.as_os_str() == "-" {
        return Err(Error::invalid(
            format!("{flag} -"),
            "outputs are files: give a path (/dev/stdout for standard output)",
        ));
    }
    if is_standard_output(path)
        && COMMAND_ARGUMENTS
            .get()
            .is_some_and(|args| args.iter().any(|a| a == "--json"))
    {
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            "is standard output, where --json prints its summary too: write one of them \
             elsewhere",
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

/// Whether `path` is the file this process's standard output goes to (`/dev/stdout`, or the
/// file it was redirected to), other than /dev/null (where nothing mixes).
fn is_standard_output(path: &Path) -> bool {
    if path
        .canonicalize()
        .is_ok_and(|p| p == Path::new("/dev/null"))
    {
        return false;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        // SAFETY: fstat writes only the struct it is given; fd 1 may be closed (then it fails).
        let mut stdout: libc::stat = unsafe { std::mem::zeroed() };
        if unsafe { libc::fstat(1, &mut stdout) } != 0 {
            return false;
        }
        std::fs::metadata(path)
            .is_ok_and(|m| m.dev() == stdout.st_dev as u64 && m.ino() == stdout.st_ino as u64)
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        false
    }
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
        // The input is named when the output reaches it by another name (a link, `..`).
        let which = match input.as_path() == path {
            true => "is a file".to_string(),
            false => format!("is {}, a file", input.display()),
        };
        return Err(Error::invalid(
            format!("{flag} {}", path.display()),
            format!(
                "{which} this command reads; nothing a command reads is overwritten: choose \
                 another output path"
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
                format!(
                    "cannot write in directory {}: {}",
                    parent.display(),
                    crate::error::io_problem(&e)
                ),
            )
        })?;
    Ok(())
}
