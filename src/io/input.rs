//! Reading a user's input file whole: only what can be a file's contents (a regular file, or a
//! pipe such as a shell's `<(...)`), and no more than the memory there is, so that a device
//! given by mistake (`/dev/zero`, `/dev/urandom`) is refused at once instead of being read
//! until memory runs out. (Devices are told apart on Unix; elsewhere the memory bound alone
//! applies.)

use crate::error::{Error, Result};
use std::io::Read;
use std::path::Path;

/// The bytes of the input file `path`.
pub fn read(path: &Path) -> Result<Vec<u8>> {
    read_at_most(path, crate::util::memory::available_memory())
}

/// The text of the input file `path` (UTF-8).
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read(path)?;
    String::from_utf8(bytes).map_err(|e| {
        Error::invalid(
            path.display().to_string(),
            format!(
                "is not UTF-8 text (byte {} is not)",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

fn read_at_most(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let name = || path.display().to_string();
    // Looked at before it is opened: opening a device can have effects of its own.
    let metadata = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if let Some(kind) = not_a_file(&metadata.file_type()) {
        return Err(Error::invalid(name(), format!("is {kind}, not a file")));
    }
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::new();
    if metadata.is_file() {
        // A regular file's length is known: refused before any of it is read.
        if metadata.len() > limit {
            return Err(too_large(path, limit));
        }
        bytes.reserve_exact(metadata.len() as usize);
    }
    (&mut file)
        .take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(path, limit));
    }
    Ok(bytes)
}

fn too_large(path: &Path, limit: u64) -> Error {
    Error::invalid(
        path.display().to_string(),
        format!(
            "is larger than the memory there is to read it into: {}",
            crate::util::memory::available_text(limit)
        ),
    )
}

/// What a file type that cannot be an input file is, in words (None for regular files,
/// directories and pipes).
#[cfg(unix)]
fn not_a_file(kind: &std::fs::FileType) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_char_device() {
        Some("a character device")
    } else if kind.is_block_device() {
        Some("a block device")
    } else if kind.is_socket() {
        Some("a socket")
    } else {
        None
    }
}

#[cfg(not(unix))]
fn not_a_file(_kind: &std::fs::FileType) -> Option<&'static str> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_are_refused_and_files_read_to_the_limit() {
        let e = read(Path::new("/dev/zero")).unwrap_err();
        assert!(e.is_user_error());
        assert_eq!(
            e.to_string(),
            "invalid /dev/zero: is a character device, not a file"
        );
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.bin");
        std::fs::write(&file, b"12345").unwrap();
        assert_eq!(read_at_most(&file, 5).unwrap(), b"12345");
        let e = read_at_most(&file, 4).unwrap_err().to_string();
        assert!(e.contains("is larger than the memory there is"), "{e}");
        let e = read(dir.path()).unwrap_err();
        assert!(e.is_user_error());
        std::fs::write(&file, [b'a', 0xff]).unwrap();
        let e = read_text(&file).unwrap_err().to_string();
        assert!(e.contains("is not UTF-8 text (byte 1 is not)"), "{e}");
    }

    #[cfg(unix)]
    #[test]
    fn a_pipe_is_read_to_its_end() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let writer = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::write(fifo, b"through a pipe").unwrap())
        };
        assert_eq!(read(&fifo).unwrap(), b"through a pipe");
        writer.join().unwrap();
    }
}
