//! What every command does with its outputs and bad input in general: exit code 2, the input named, nothing left behind, existing files replaced only on success, interrupted runs.

use super::*;

#[test]
fn bad_inputs_exit_2_naming_the_input_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out.ssa");
    let out_s = out.to_str().unwrap();
    let p = |n: &str| d.join(n).to_str().unwrap().to_string();

    // Missing file.
    let o = run(&["analyze", "--backend", "cpu", &p("nope.png"), "-o", out_s]);
    assert_user_error(&o, "nope.png", d, &[]);

    // Truncated / corrupt image.
    let png = std::fs::read(fixture_path("cells32.png")).unwrap();
    std::fs::write(d.join("trunc.png"), &png[..png.len() / 2]).unwrap();
    let o = run(&["analyze", "--backend", "cpu", &p("trunc.png"), "-o", out_s]);
    assert_user_error(&o, "trunc.png", d, &["trunc.png"]);
    std::fs::write(d.join("garbage.png"), b"this is not an image").unwrap();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        &p("garbage.png"),
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "garbage.png", d, &["trunc.png", "garbage.png"]);
    let keep = [
        "trunc.png",
        "garbage.png",
        "tiny.png",
        "wide.png",
        "mask.png",
    ];

    // Tiny exemplar.
    image::RgbImage::new(8, 8).save(d.join("tiny.png")).unwrap();
    let o = run(&["analyze", "--backend", "cpu", &p("tiny.png"), "-o", out_s]);
    assert_user_error(&o, "at least 16", d, &keep);

    // Mismatched Ex/Ey/Ez sizes.
    image::RgbImage::new(40, 32)
        .save(d.join("wide.png"))
        .unwrap();
    let c = fixture_path("cells32.png");
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "--ey",
        &p("wide.png"),
        "--ez",
        c.to_str().unwrap(),
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "--ey", d, &keep);

    // A mask of another size.
    image::GrayImage::new(20, 20)
        .save(d.join("mask.png"))
        .unwrap();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "--feature-mask",
        &p("mask.png"),
        "-o",
        out_s,
    ]);
    assert_user_error(&o, "mask", d, &keep);

    // Output path is a directory, or in a missing directory.
    std::fs::create_dir(d.join("adir")).unwrap();
    let keep_dir = [&keep[..], &["adir"]].concat();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "-o",
        &p("adir"),
    ]);
    assert_user_error(&o, "is a directory", d, &keep_dir);
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        c.to_str().unwrap(),
        "-o",
        &p("missing/out.ssa"),
    ]);
    assert_user_error(&o, "does not exist", d, &keep_dir);

    // A corrupt .ssa given to inspect.
    std::fs::write(d.join("bad.ssa"), b"SOLIDSSA garbage").unwrap();
    let keep_bad = [&keep_dir[..], &["bad.ssa"]].concat();
    let o = run(&["inspect", &p("bad.ssa")]);
    assert_user_error(&o, "bad.ssa", d, &keep_bad);

    // Bad flag values are clap's: also exit 2.
    let o = run(&[
        "analyze",
        "--backend",
        "quantum",
        c.to_str().unwrap(),
        "-o",
        out_s,
    ]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn existing_output_is_replaced_only_on_success() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.ssa");
    std::fs::write(&out, b"precious").unwrap();
    let o = run(&[
        "analyze",
        "--backend",
        "cpu",
        "/nonexistent.png",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
}

/// An interrupt (Ctrl-C) while the volume is being streamed to its file deletes the partial file.
#[test]
#[cfg(unix)]
fn an_interrupted_synthesis_leaves_no_partial_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = tempfile::tempdir().unwrap();
    let mut child = bin()
        .env("SOLIDSYNTH_CACHE_DIR", cache.path())
        .args(["synth", "--size", "256", "--backend", "cpu", "-q", "-o"])
        .arg(d.join("v.nrrd"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    let partial = loop {
        let names: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .collect();
        if let Some(n) = names.iter().find(|n| n.ends_with(".partial")) {
            break n.clone();
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "exited before writing: {names:?}"
        );
        assert!(
            started.elapsed().as_secs() < 120,
            "no partial output appeared"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status:?}");
    let left: Vec<_> = std::fs::read_dir(d).unwrap().collect();
    assert!(left.is_empty(), "{partial} interrupted, left {left:?}");
}

/// llvmpipe runs 16 lanes wide on an AVX-512 host unless the user chose a width: the process
/// sets `LP_NATIVE_VECTOR_WIDTH=512` only when it is unset (`adapters` names the width). Under
/// `CI` lavapipe is the project's Vulkan device (.ci/run installs it), so its absence fails.
#[test]
fn lavapipe_runs_at_the_host_vector_width_unless_the_user_chose_one() {
    let adapters = |width: Option<&str>| {
        let mut c = bin();
        c.arg("adapters");
        match width {
            Some(w) => c.env("LP_NATIVE_VECTOR_WIDTH", w),
            None => c.env_remove("LP_NATIVE_VECTOR_WIDTH"),
        };
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let listed = adapters(None);
    if !listed.contains("llvmpipe") {
        assert!(
            std::env::var_os("CI").is_none(),
            "no lavapipe adapter under CI: {listed}"
        );
        return;
    }
    #[cfg(target_arch = "x86_64")]
    let wide = std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512vl");
    #[cfg(not(target_arch = "x86_64"))]
    let wide = false;
    if wide {
        assert!(listed.contains("512 bits"), "{listed}");
    }
    let chosen = adapters(Some("256"));
    assert!(chosen.contains("256 bits"), "{chosen}");
}

/// A subcommand's name is not a path: `ptm capture -o capture` writes ./capture (the check that
/// no output is also an input reads the command's arguments only). An output that is an input
/// is still refused.
#[test]
fn an_output_named_like_its_subcommand_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let o = bin()
        .current_dir(dir.path())
        .args([
            "ptm", "capture", "--size", "40", "--lights", "12", "-o", "capture",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(dir.path().join("capture").is_dir());
    let image = dir.path().join("e.png");
    std::fs::copy(fixture_path("cells32.png"), &image).unwrap();
    let p = image.to_str().unwrap();
    let o = run(&["analyze", p, "--backend", "cpu", "-o", p]);
    assert_user_error(
        &o,
        "is also given as an input",
        dir.path(),
        &["capture", "e.png"],
    );
}

/// Conflicts found by the checks before any work: an output that is a hard link to an input,
/// an output inside the `--slices` directory, an analysis flag beside an `.ssa`; and a volume
/// larger than the memory budget refused before its data is decoded.
#[test]
fn conflicting_outputs_and_inputs_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ssa = analyze_cells(d);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    // A hard link to the analysis, given as the output: the analysis is kept.
    let link = d.join("link.ssa");
    std::fs::hard_link(&ssa, &link).unwrap();
    let before = std::fs::read(&ssa).unwrap();
    let o = run(&[
        "synth",
        &s(&link),
        "--size",
        "8",
        "--backend",
        "cpu",
        "--format",
        "nrrd",
        "-o",
        &s(&ssa),
    ]);
    assert_user_error(&o, "is also given as an input", d, &["c.ssa", "link.ssa"]);
    assert_eq!(std::fs::read(&ssa).unwrap(), before);
    // An output inside the slices' directory.
    let slices = d.join("slices");
    std::fs::create_dir(&slices).unwrap();
    for (flag, target) in [("--sheet", "slices/sheet.png"), ("-o", "slices/v.nrrd")] {
        let target = s(&d.join(target));
        let ssa_arg = s(&ssa);
        let mut args = vec!["synth", &ssa_arg, "--size", "8", "--backend", "cpu"];
        let slices_arg = s(&slices);
        args.extend(["--slices", &slices_arg]);
        let other = s(&d.join("v.nrrd"));
        match flag {
            "-o" => args.extend(["-o", &target]),
            _ => args.extend(["-o", &other, flag, &target]),
        }
        let o = run(&args);
        assert_user_error(
            &o,
            "holds that output alone",
            d,
            &["c.ssa", "link.ssa", "slices"],
        );
        assert!(std::fs::read_dir(&slices).unwrap().next().is_none());
    }
    // A voxel size whose VDB transform (1 / size^2) would not be finite.
    let o = run(&[
        "synth",
        &s(&ssa),
        "--size",
        "8",
        "--backend",
        "cpu",
        "--voxel-size",
        "1e-300",
        "-o",
        &s(&d.join("v.vdb")),
    ]);
    assert_user_error(&o, "--voxel-size", d, &["c.ssa", "link.ssa", "slices"]);
    // `--periodic` is an analysis input, held by the .ssa.
    let o = run(&[
        "synth",
        &s(&ssa),
        "--periodic",
        "--size",
        "8",
        "--backend",
        "cpu",
        "-o",
        &s(&d.join("p.nrrd")),
    ]);
    assert_user_error(&o, "--periodic", d, &["c.ssa", "link.ssa", "slices"]);
    // A gzip volume of 16 MiB declared, under a budget of 1 MiB.
    let mut big =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 256 256 256\nencoding: gzip\n\n".to_vec();
    big.extend(solidsynth::io::nrrd::gzip_bytes(&vec![
        0u8;
        256 * 256 * 256
    ]));
    let big_path = d.join("big.nrrd");
    std::fs::write(&big_path, big).unwrap();
    let o = bin()
        .env("SOLIDSYNTH_MEMORY_BUDGET_MIB", "1")
        .args([
            "gradient",
            "vectorize",
            &s(&big_path),
            "-o",
            &s(&d.join("v.gsolid")),
        ])
        .output()
        .unwrap();
    assert_user_error(
        &o,
        "16.0 MiB, more memory than there is: 1.0 MiB is available under \
         SOLIDSYNTH_MEMORY_BUDGET_MIB=1",
        d,
        &["c.ssa", "link.ssa", "slices", "big.nrrd"],
    );
}

/// A PNG that declares `width` x `height` RGB pixels and holds none: its signature, header and
/// end chunks and no pixel data.
fn png_header_only(width: u32, height: u32) -> Vec<u8> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= b as u32;
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        let body: Vec<u8> = kind.iter().chain(data).copied().collect();
        c.extend_from_slice(&body);
        c.extend_from_slice(&crc32(&body).to_be_bytes());
        c
    };
    let mut header = width.to_be_bytes().to_vec();
    header.extend_from_slice(&height.to_be_bytes());
    header.extend_from_slice(&[8, 2, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &header));
    // An empty zlib stream.
    png.extend(chunk(
        b"IDAT",
        &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
    ));
    png.extend(chunk(b"IEND", &[]));
    png
}

#[test]
fn output_names_and_values_get_messages_that_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let in_dir = |args: &[&str]| bin().current_dir(d).args(args).output().unwrap();
    std::fs::write(d.join("file"), b"kept").unwrap();
    let kept = ["file", "huge.png", "loop.nrrd"];
    std::os::unix::fs::symlink("loop.nrrd", d.join("loop.nrrd")).unwrap();
    let cut = [
        "cut",
        "--backend",
        "cpu",
        "--origin",
        "0,0,0",
        "--normal",
        "0,0,1",
        "--size",
        "8",
    ];
    let with = |base: &[&str], extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|a| a.to_string()).collect()
    };
    let cases: Vec<(Vec<String>, &str)> = vec![
        // An output named for another format than the one written there.
        (
            with(&cut, &["-o", "c.nrrd"]),
            "is written as a PNG image: give a name ending in .png",
        ),
        (
            with(&["analyze", "-o", "a.png"], &[]),
            "is written as an analysis",
        ),
        (
            with(
                &["synth", "--size", "16", "--sheet", "s.tif", "-o", "v.nrrd"],
                &[],
            ),
            "--sheet s.tif: is written as a PNG image",
        ),
        (
            with(&["gradient", "synth", "--size", "16", "-o", "g.nrrd"], &[]),
            "ending in .gsolid",
        ),
        // A path that cannot be a file, named as such.
        (with(&cut, &["-o", "newdir/"]), "ends in /"),
        (
            with(&cut, &["-o", "file/c.png"]),
            "file is a file, not a directory",
        ),
        (
            with(&["man", "-o", "file"], &[]),
            "exists and is not a directory",
        ),
        // Values named for what they must be, not for their type's range.
        (
            with(&cut, &["--coarse-cache", "-1", "-o", "c.png"]),
            "a multiple of 64 in 64..=1024",
        ),
        (
            with(&cut, &["--coarse-cache=100", "-o", "c.png"]),
            "a multiple of 64 in 64..=1024",
        ),
        (
            with(&cut, &["--up", "0,0,0", "-o", "c.png"]),
            "--up: must not be the zero vector",
        ),
        (
            with(&["synth", "--size", "4294967296", "-o", "v.nrrd"], &[]),
            "expected a whole number in 8..=2048",
        ),
        // Standard output is not a file name, and not shared with a --json summary.
        (with(&cut, &["-o", "-"]), "outputs are files"),
        (
            with(&["synth", "--size", "8", "-o", "loop.nrrd"], &[]),
            "a symbolic link that leads back to itself",
        ),
        (
            with(&cut, &["--json", "-o", "/dev/stdout"]),
            "where --json prints its summary too",
        ),
        // Benchmarks check their sizes up front too (a size 0 panicked).
        (
            with(
                &["bench", "gradient-render", "--sizes", "0", "--no-gpu"],
                &[],
            ),
            "--sizes",
        ),
        (
            with(
                &["bench", "ptm", "--relight-size", "1000000", "--no-gpu"],
                &[],
            ),
            "--relight-size",
        ),
    ];
    for (args, needle) in cases {
        let o = in_dir(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert_user_error(&o, needle, d, &kept);
    }
    assert_eq!(std::fs::read(d.join("file")).unwrap(), b"kept");
    // A directory where one man page goes: refused before any page is written.
    std::fs::create_dir_all(d.join("man/solidsynth-synth.1")).unwrap();
    let o = in_dir(&["man", "-o", "man"]);
    assert_user_error(&o, "holds a directory", d, &["file", "man", "loop.nrrd"]);
    assert_eq!(std::fs::read_dir(d.join("man")).unwrap().count(), 1);
    std::fs::remove_dir_all(d.join("man")).unwrap();
    // An image too large is named by its size before it is decoded.
    std::fs::write(d.join("huge.png"), png_header_only(100_000, 100_000)).unwrap();
    let o = in_dir(&["analyze", "--backend", "cpu", "huge.png", "-o", "h.ssa"]);
    assert_user_error(
        &o,
        "image is 100000x100000; exemplars are at most 2048 pixels a side",
        d,
        &kept,
    );
    // A memory budget of nothing is named as the limit.
    let o = bin()
        .current_dir(d)
        .env("SOLIDSYNTH_MEMORY_BUDGET_MIB", "0")
        .args(["synth", "--backend", "cpu", "--size", "16", "-o", "v.nrrd"])
        .output()
        .unwrap();
    assert_user_error(
        &o,
        "0 bytes is available under SOLIDSYNTH_MEMORY_BUDGET_MIB=0",
        d,
        &kept,
    );
}
