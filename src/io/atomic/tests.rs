use super::*;

/// Every commit syncs its target's directory after the rename (files, and directories of
/// outputs), so the new entry survives a crash.
#[test]
fn a_commit_syncs_the_directory_it_renamed_into() {
    use std::sync::atomic::Ordering;
    let dir = tempfile::tempdir().unwrap();
    let before = DIRECTORY_SYNCS.load(Ordering::Relaxed);
    write_file(&dir.path().join("a.bin"), b"abc").unwrap();
    assert!(DIRECTORY_SYNCS.load(Ordering::Relaxed) > before);
    let before = DIRECTORY_SYNCS.load(Ordering::Relaxed);
    let mut outputs = Outputs::new();
    outputs.write_file(&dir.path().join("b.bin"), b"b").unwrap();
    outputs.commit().unwrap();
    assert!(DIRECTORY_SYNCS.load(Ordering::Relaxed) > before);
    assert_eq!(std::fs::read(dir.path().join("b.bin")).unwrap(), b"b");
}

/// A named pipe (like /dev/null, not a regular file) is written in place and stays a pipe:
/// renaming a staged file over it would replace it. (`synth -o /dev/null` run as root did.)
#[test]
#[cfg(unix)]
fn a_pipe_or_device_is_written_in_place_not_replaced() {
    use std::io::Read;
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let pipe = dir.path().join("pipe");
    let c_path = std::ffi::CString::new(pipe.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0);
    let reader = {
        let pipe = pipe.clone();
        std::thread::spawn(move || {
            let mut got = Vec::new();
            std::fs::File::open(pipe)
                .unwrap()
                .read_to_end(&mut got)
                .unwrap();
            got
        })
    };
    check_output_path(&pipe, "-o").unwrap();
    write_file(&pipe, b"through the pipe").unwrap();
    // Checked before waiting for the reader, which a replaced pipe would leave blocked.
    assert!(std::fs::symlink_metadata(&pipe)
        .unwrap()
        .file_type()
        .is_fifo());
    assert_eq!(reader.join().unwrap(), b"through the pipe");
    // Nothing was staged beside it.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// A symbolic link is followed: the file it names gets the output, and the link stays.
#[test]
#[cfg(unix)]
fn a_symbolic_link_keeps_pointing_at_the_replaced_file() {
    let dir = tempfile::tempdir().unwrap();
    let real = dir.path().join("real.bin");
    let link = dir.path().join("link.bin");
    std::fs::write(&real, b"old").unwrap();
    std::os::unix::fs::symlink(&real, &link).unwrap();
    check_output_path(&link, "-o").unwrap();
    write_file(&link, b"new").unwrap();
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&real).unwrap(), b"new");
}

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
fn staged_outputs_appear_together_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("a.bin"), b"old").unwrap();
    let names = |d: &Path| {
        let mut n: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        n.sort();
        n
    };
    // Dropped before commit (a later output failed): nothing new, the old file kept.
    let mut outputs = Outputs::new();
    outputs.write_file(&d.join("a.bin"), b"new").unwrap();
    outputs.write_file(&d.join("b.bin"), b"b").unwrap();
    let staging = outputs.directory(&d.join("slices")).unwrap();
    std::fs::write(staging.join("s0.png"), b"s").unwrap();
    drop(outputs);
    assert_eq!(names(d), ["a.bin"]);
    assert_eq!(std::fs::read(d.join("a.bin")).unwrap(), b"old");
    // Committed: all of them, and no temporaries; an empty directory is replaced.
    std::fs::create_dir(d.join("slices")).unwrap();
    let mut outputs = Outputs::new();
    outputs.write_file(&d.join("a.bin"), b"new").unwrap();
    outputs.write_file(&d.join("b.bin"), b"b").unwrap();
    let staging = outputs.directory(&d.join("slices")).unwrap();
    std::fs::write(staging.join("s0.png"), b"s").unwrap();
    outputs.commit().unwrap();
    assert_eq!(names(d), ["a.bin", "b.bin", "slices"]);
    assert_eq!(std::fs::read(d.join("a.bin")).unwrap(), b"new");
    assert_eq!(std::fs::read(d.join("slices/s0.png")).unwrap(), b"s");
    // A directory that is not empty is not replaced, the staged copy goes away, and the
    // files staged with it are not put in place either.
    let mut outputs = Outputs::new();
    outputs.write_file(&d.join("c.bin"), b"c").unwrap();
    let staging = outputs.directory(&d.join("slices")).unwrap();
    std::fs::write(staging.join("s1.png"), b"t").unwrap();
    assert!(outputs.commit().is_err());
    assert_eq!(names(d), ["a.bin", "b.bin", "slices"]);
    assert_eq!(names(&d.join("slices")), ["s0.png"]);
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

/// When an output cannot be put in place (here a name too long for the file system), the
/// outputs already placed are taken back: a replaced file has its former contents again, a new
/// file and a new directory are gone, an empty directory stays, and no temporary is left.
#[test]
fn a_failed_commit_restores_the_outputs_it_had_placed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("kept.bin"), b"the user's").unwrap();
    std::fs::create_dir(d.join("empty")).unwrap();
    let mut outputs = Outputs::new();
    let slices = outputs.directory(&d.join("empty")).unwrap();
    std::fs::write(slices.join("slice.png"), b"s").unwrap();
    let fresh = outputs.directory(&d.join("fresh")).unwrap();
    std::fs::write(fresh.join("slice.png"), b"s").unwrap();
    outputs.write_file(&d.join("kept.bin"), b"new").unwrap();
    outputs.write_file(&d.join("new.bin"), b"new").unwrap();
    outputs
        .write_file(&d.join(format!("{}.bin", "x".repeat(300))), b"never placed")
        .unwrap();
    assert!(outputs.commit().is_err());
    assert_eq!(std::fs::read(d.join("kept.bin")).unwrap(), b"the user's");
    let mut left: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["empty", "kept.bin"]);
    assert_eq!(std::fs::read_dir(d.join("empty")).unwrap().count(), 0);
}

/// A directory output named by a symbolic link to an empty directory fills that directory and
/// keeps the link (as a file output keeps its link).
#[test]
#[cfg(unix)]
fn a_link_to_an_empty_directory_is_filled_through() {
    let dir = tempfile::tempdir().unwrap();
    let (real, link) = (dir.path().join("real"), dir.path().join("link"));
    std::fs::create_dir(&real).unwrap();
    std::os::unix::fs::symlink(&real, &link).unwrap();
    check_output_dir(&link, "--slices").unwrap();
    let mut outputs = Outputs::new();
    let staging = outputs.directory(&link).unwrap();
    std::fs::write(staging.join("slice.png"), b"s").unwrap();
    outputs.commit().unwrap();
    assert!(link.is_symlink());
    assert_eq!(std::fs::read(real.join("slice.png")).unwrap(), b"s");
}
