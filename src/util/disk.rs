//! Free disk space, so that an output too large for its file system is refused before it is
//! computed rather than found when the disk fills.

use std::path::Path;

/// The bytes an unprivileged process may still write on the file system that holds `path` (or,
/// for a path not made yet, its nearest existing ancestor); None where that is unknown.
pub fn free_bytes(path: &Path) -> Option<u64> {
    let mut existing = path;
    while !existing.exists() {
        existing = match existing.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
    }
    free_bytes_at(existing)
}

#[cfg(unix)]
fn free_bytes_at(path: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let name = std::ffi::CString::new(path.as_os_str().as_bytes()).ok()?;
    // SAFETY: statvfs reads the NUL-terminated path and writes only the struct it is given.
    let mut stats: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(name.as_ptr(), &mut stats) } != 0 {
        return None;
    }
    // (The fields' widths differ between targets.)
    #[allow(clippy::unnecessary_cast)]
    let free = (stats.f_bavail as u64).saturating_mul(stats.f_frsize as u64);
    Some(free)
}

#[cfg(not(unix))]
fn free_bytes_at(_path: &Path) -> Option<u64> {
    None
}

#[cfg(test)]
mod tests {
    use super::free_bytes;

    #[test]
    fn free_space_is_read_for_new_paths_through_their_ancestors() {
        let dir = tempfile::tempdir().unwrap();
        let here = free_bytes(dir.path()).expect("a temporary directory's file system");
        assert!(here > 0);
        let deeper = free_bytes(&dir.path().join("new/a/b.zarr")).unwrap();
        // The same file system; other writers may change the count between the two reads.
        assert!(deeper.abs_diff(here) < 1 << 30);
        assert!(free_bytes(std::path::Path::new("relative-new-dir/x")).is_some());
    }
}
