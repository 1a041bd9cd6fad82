//! `region -o OUT.zarr`: a chunked Zarr v3 array holding the voxels of the same box's `.npy`
//! (chunk by chunk, edge chunks padded with zeros), filled alike by one process or by several
//! sharing its chunks (`--chunks-of`), completed by `--resume` without touching the chunks
//! there, never replacing what is not this array. zarr-python reads it back when
//! `$SOLIDSYNTH_TEST_PYTHON` has it (skipped with a note otherwise).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The box of most tests: 40 x 24 x 32 voxels (edge chunks on x and y at --chunk 16), off the
/// brick grid.
const BOX: &str = "--box=-7,3,5,33,27,37";
const DIMS: [usize; 3] = [40, 24, 32];

fn bin(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_solidsynth"));
    c.current_dir(dir)
        .env("SOLIDSYNTH_LOG", "warn")
        .env("SOLIDSYNTH_MEMORY_BUDGET_MIB", "4096")
        .env("SOLIDSYNTH_CACHE_DIR", dir.join("cache"));
    c
}

fn run(dir: &Path, args: &[&str]) -> Output {
    bin(dir).args(args).output().unwrap()
}

fn ok(dir: &Path, args: &[&str]) -> Output {
    let out = run(dir, args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Exit code 2 with `needle` in the message.
fn refused(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(stderr.contains(needle), "expected '{needle}' in: {stderr}");
    assert!(!stderr.contains("(os error"), "{stderr}");
}

/// The cells fixture analysed (CPU) into `dir`/c.ssa: the input of every region here.
fn analyze_cells(dir: &Path) {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/cells32.png");
    ok(
        dir,
        &[
            "analyze",
            "--backend",
            "cpu",
            "--periodic",
            fixture.to_str().unwrap(),
            "-o",
            "c.ssa",
        ],
    );
}

/// `region c.ssa` of `bx` with seed 3 on the CPU, then `extra`.
fn region(dir: &Path, bx: &str, extra: &[&str]) -> Output {
    let mut args = vec!["region", "c.ssa", bx, "--seed", "3", "--backend", "cpu"];
    args.extend_from_slice(extra);
    run(dir, &args)
}

fn region_ok(dir: &Path, bx: &str, extra: &[&str]) -> Output {
    let out = region(dir, bx, extra);
    assert!(
        out.status.success(),
        "{extra:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Every file under `root` by its path relative to it ('/'-separated), with its bytes.
fn tree(root: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(dir: &Path, prefix: &str, out: &mut BTreeMap<String, Vec<u8>>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let entry = entry.unwrap();
            let name = format!("{prefix}{}", entry.file_name().to_string_lossy());
            if entry.file_type().unwrap().is_dir() {
                walk(&entry.path(), &format!("{name}/"), out);
            } else {
                out.insert(name, std::fs::read(entry.path()).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(root, "", &mut out);
    out
}

fn metadata(root: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(root.join("zarr.json")).unwrap()).unwrap()
}

/// The data of a `.npy` file (its header skipped: its length is at bytes 8..10).
fn npy_data(path: &Path) -> Vec<u8> {
    let bytes = std::fs::read(path).unwrap();
    let header = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytes[10 + header..].to_vec()
}

/// Every chunk of the array at `root` holds the voxels of `volume` (C order of (Z, Y, X, C),
/// `dims` x, y, z) where it covers the volume, and zeros past it.
fn assert_chunks_hold(root: &Path, volume: &[u8], dims: [usize; 3], chunk: usize) {
    let shape = metadata(root)["shape"].clone();
    let channels = shape[3].as_u64().unwrap() as usize;
    assert_eq!(
        shape,
        serde_json::json!([dims[2], dims[1], dims[0], channels])
    );
    assert_eq!(volume.len(), dims.iter().product::<usize>() * channels);
    let grid = dims.map(|d| d.div_ceil(chunk));
    for iz in 0..grid[2] {
        for iy in 0..grid[1] {
            for ix in 0..grid[0] {
                let key = format!("c/{iz}/{iy}/{ix}/0");
                let data = std::fs::read(root.join(&key)).unwrap();
                assert_eq!(data.len(), chunk.pow(3) * channels, "{key}");
                for z in 0..chunk {
                    for y in 0..chunk {
                        for x in 0..chunk {
                            let at = ((z * chunk + y) * chunk + x) * channels;
                            let got = &data[at..at + channels];
                            let [gx, gy, gz] = [ix * chunk + x, iy * chunk + y, iz * chunk + z];
                            if gx < dims[0] && gy < dims[1] && gz < dims[2] {
                                let from = ((gz * dims[1] + gy) * dims[0] + gx) * channels;
                                assert_eq!(
                                    got,
                                    &volume[from..from + channels],
                                    "{key} at ({x}, {y}, {z})"
                                );
                            } else {
                                assert!(
                                    got.iter().all(|&b| b == 0),
                                    "{key} pad at ({x}, {y}, {z})"
                                );
                            }
                        }
                    }
                }
            }
        }
    }
}

fn summary(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn an_array_holds_the_npy_voxels_in_chunks_and_shares_fill_the_same_array() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    analyze_cells(d);
    region_ok(d, BOX, &["-o", "a.zarr", "--chunk", "16"]);
    region_ok(d, BOX, &["-o", "v.npy"]);
    assert_chunks_hold(&d.join("a.zarr"), &npy_data(&d.join("v.npy")), DIMS, 16);
    // The metadata: a Zarr v3 uint8 array in 16^3 chunks, keys c/z/y/x/0, raw bytes, and where
    // it lies in the solid.
    let m = metadata(&d.join("a.zarr"));
    let channels = m["shape"][3].clone();
    assert_eq!(m["zarr_format"], 3);
    assert_eq!(m["node_type"], "array");
    assert_eq!(m["data_type"], "uint8");
    assert_eq!(m["fill_value"], 0);
    assert_eq!(m["chunk_grid"]["name"], "regular");
    assert_eq!(
        m["chunk_grid"]["configuration"]["chunk_shape"],
        serde_json::json!([16, 16, 16, channels])
    );
    assert_eq!(m["chunk_key_encoding"]["name"], "default");
    assert_eq!(m["chunk_key_encoding"]["configuration"]["separator"], "/");
    assert_eq!(m["codecs"], serde_json::json!([{"name": "bytes"}]));
    assert_eq!(
        m["dimension_names"],
        serde_json::json!(["z", "y", "x", "c"])
    );
    assert_eq!(
        m["attributes"]["solidsynth"]["origin"],
        serde_json::json!([-7, 3, 5])
    );
    assert_eq!(m["attributes"]["solidsynth"]["seed"], 3);
    // zarr.json and the 2 x 2 x 3 chunks, nothing else (no temporaries).
    let a = tree(&d.join("a.zarr"));
    assert_eq!(a.len(), 1 + 12, "{:?}", a.keys().collect::<Vec<_>>());

    // Two processes started together (threads waiting on each) on a new path, each with half
    // the chunks, make the same array (the same zarr.json from both, whichever put it there).
    let handles: Vec<_> = ["0/2", "1/2"]
        .into_iter()
        .map(|share| {
            let mut command = bin(d);
            command
                .args(["region", "c.ssa", BOX, "--seed", "3", "--backend", "cpu"])
                .args(["-o", "b.zarr", "--chunk", "16", "--chunks-of", share]);
            std::thread::spawn(move || command.output().unwrap())
        })
        .collect();
    for h in handles {
        let out = h.join().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert!(
        tree(&d.join("b.zarr")) == a,
        "shared fill differs from one process's"
    );

    // A share's chunks are not recomputed over themselves without --resume.
    let out = region(
        d,
        BOX,
        &["-o", "b.zarr", "--chunk", "16", "--chunks-of", "0/2"],
    );
    refused(&out, "--resume");
    assert!(tree(&d.join("b.zarr")) == a);
    // With it, a share whose chunks are all there writes nothing (chunks 0, 3, 6, 9 of 0/3).
    let out = region_ok(
        d,
        BOX,
        &[
            "-o",
            "b.zarr",
            "--chunk",
            "16",
            "--chunks-of",
            "0/3",
            "--resume",
            "--json",
        ],
    );
    let s = summary(&out);
    assert_eq!(s["chunks_assigned"], 4, "{s}");
    assert_eq!(s["chunks_written"], 0, "{s}");
    assert_eq!(s["chunks_skipped"], 4, "{s}");
    assert_eq!(s["chunks"], 12);
}

#[test]
fn resume_rewrites_exactly_the_missing_or_damaged_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    analyze_cells(d);
    let root = d.join("r.zarr");
    region_ok(d, BOX, &["-o", "r.zarr", "--chunk", "16"]);
    let before = tree(&root);
    let times: BTreeMap<String, std::time::SystemTime> = before
        .keys()
        .map(|k| {
            (
                k.clone(),
                std::fs::metadata(root.join(k)).unwrap().modified().unwrap(),
            )
        })
        .collect();
    let redo = ["c/0/0/0/0", "c/1/1/2/0", "c/0/1/1/0"];
    std::fs::remove_file(root.join(redo[0])).unwrap();
    std::fs::remove_file(root.join(redo[1])).unwrap();
    // A chunk of the wrong size (not one we wrote: ours are complete once there) is redone too.
    std::fs::write(root.join(redo[2]), b"damaged").unwrap();
    let out = region_ok(
        d,
        BOX,
        &["-o", "r.zarr", "--chunk", "16", "--resume", "--json"],
    );
    let s = summary(&out);
    assert_eq!(s["chunks_written"], 3, "{s}");
    assert_eq!(s["chunks_skipped"], 9, "{s}");
    assert_eq!(s["created"], false);
    assert!(tree(&root) == before, "resumed array differs");
    for (key, time) in &times {
        let now = std::fs::metadata(root.join(key))
            .unwrap()
            .modified()
            .unwrap();
        if !redo.contains(&key.as_str()) {
            assert_eq!(&now, time, "{key} was rewritten");
        }
    }
    // Without --resume an existing array is refused, naming it, and left alone.
    let out = region(d, BOX, &["-o", "r.zarr", "--chunk", "16"]);
    refused(&out, "r.zarr");
    refused(&out, "--resume");
    assert!(tree(&root) == before);
}

#[test]
#[cfg(unix)]
fn an_interrupted_array_keeps_its_finished_chunks_and_resume_completes_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    analyze_cells(d);
    let root = d.join("i.zarr");
    let bx = "--box=0,0,0,48,48,48";
    let mut child = bin(d)
        .args([
            "region",
            "c.ssa",
            bx,
            "--seed",
            "3",
            "--backend",
            "cpu",
            "-q",
        ])
        .args(["-o", "i.zarr", "--chunk", "16"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let chunks = |root: &Path| -> Vec<String> {
        if !root.join("c").is_dir() {
            return Vec::new();
        }
        tree(root)
            .into_keys()
            .filter(|k| k.starts_with("c/") && k.ends_with("/0"))
            .collect()
    };
    let started = std::time::Instant::now();
    let finished_first = loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "{status:?}");
            break true;
        }
        if !chunks(&root).is_empty() {
            break false;
        }
        assert!(started.elapsed().as_secs() < 300, "no chunk appeared");
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    if !finished_first {
        let killed = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        // It may have finished between the look and the signal.
        assert!(matches!(status.code(), Some(130) | Some(0)), "{status:?}");
    } else {
        eprintln!("note: the region finished before it could be interrupted");
    }
    // No temporaries left, and every chunk there is complete.
    let files = tree(&root);
    assert!(
        files.keys().all(|k| !k.contains(".solidsynth-")),
        "temporaries left: {:?}",
        files.keys().collect::<Vec<_>>()
    );
    let channels = metadata(&root)["shape"][3].as_u64().unwrap() as usize;
    let present = chunks(&root);
    for k in &present {
        assert_eq!(files[k].len(), 16 * 16 * 16 * channels, "{k}");
    }
    let out = region_ok(
        d,
        bx,
        &["-o", "i.zarr", "--chunk", "16", "--resume", "--json"],
    );
    let s = summary(&out);
    assert_eq!(s["chunks_skipped"], present.len());
    assert_eq!(s["chunks_written"], 27 - present.len());
    assert_eq!(chunks(&root).len(), 27);
    // What was there before the resume is unchanged.
    let after = tree(&root);
    for k in &present {
        assert!(after[k] == files[k], "{k} changed");
    }
}

#[test]
fn existing_content_that_is_not_this_array_is_refused_and_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    analyze_cells(d);
    // A directory of something else, with or without --resume or --chunks-of.
    std::fs::create_dir(d.join("x.zarr")).unwrap();
    std::fs::write(d.join("x.zarr/notes.txt"), b"mine").unwrap();
    for extra in [&[][..], &["--resume"][..], &["--chunks-of", "0/2"][..]] {
        let mut args = vec!["-o", "x.zarr", "--chunk", "16"];
        args.extend_from_slice(extra);
        refused(&region(d, BOX, &args), "x.zarr");
        assert_eq!(tree(&d.join("x.zarr")).len(), 1);
    }
    // A file.
    std::fs::write(d.join("f.zarr"), b"a file").unwrap();
    refused(&region(d, BOX, &["-o", "f.zarr", "--resume"]), "f.zarr");
    assert_eq!(std::fs::read(d.join("f.zarr")).unwrap(), b"a file");
    // An array of another box or other settings: refused naming what differs.
    let small = "--box=0,0,0,16,16,16";
    region_ok(d, small, &["-o", "y.zarr", "--chunk", "16"]);
    let before = tree(&d.join("y.zarr"));
    let out = region(
        d,
        "--box=0,0,0,32,16,16",
        &["-o", "y.zarr", "--chunk", "16", "--resume"],
    );
    refused(&out, "shape");
    let out = region(d, small, &["-o", "y.zarr", "--chunk", "8", "--resume"]);
    refused(&out, "chunk_shape");
    let mut args = vec!["region", "c.ssa", small, "--seed", "9", "--backend", "cpu"];
    args.extend_from_slice(&["-o", "y.zarr", "--chunk", "16", "--chunks-of", "0/2"]);
    refused(&run(d, &args), "seed");
    assert!(tree(&d.join("y.zarr")) == before);
    // Nothing else appeared beside them.
    let mut names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "cache")
        .collect();
    names.sort();
    assert_eq!(names, ["c.ssa", "f.zarr", "x.zarr", "y.zarr"]);
}

#[test]
fn bad_zarr_flags_exit_2_naming_the_flag_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = ["region", "--box", "0,0,0,16,16,16", "--backend", "cpu"];
    // --chunk: 8..=512 voxels, a multiple of 4 (the engine's brick edge).
    for bad in ["0", "6", "4", "516", "x"] {
        let mut args = common.to_vec();
        args.extend_from_slice(&["-o", "a.zarr", "--chunk", bad]);
        refused(&run(d, &args), "--chunk");
    }
    for bad in ["3/2", "2/2", "0/0", "x/2", "2"] {
        let mut args = common.to_vec();
        args.extend_from_slice(&["-o", "a.zarr", "--chunks-of", bad]);
        refused(&run(d, &args), "--chunks-of");
    }
    // A share with no chunk of its own (the 16^3 box is one chunk) is a mistake, not a no-op.
    let mut args = common.to_vec();
    args.extend_from_slice(&["-o", "a.zarr", "--chunks-of", "1/2"]);
    refused(&run(d, &args), "would compute none");
    // An array larger than any disk (768 TiB): refused before it is made, not when the disk
    // fills.
    let huge = [
        "region",
        "--box",
        "0,0,0,65536,65536,65536",
        "--backend",
        "cpu",
        "-o",
        "huge.zarr",
    ];
    refused(&run(d, &huge), "on disk, and");
    // The Zarr flags belong to Zarr outputs, and outputs made from the whole volume do not go
    // with one.
    for (extra, flag) in [
        (&["--chunk", "16"][..], "--chunk"),
        (&["--resume"][..], "--resume"),
        (&["--chunks-of", "0/2"][..], "--chunks-of"),
    ] {
        let mut args = common.to_vec();
        args.extend_from_slice(&["-o", "v.nrrd"]);
        args.extend_from_slice(extra);
        refused(&run(d, &args), flag);
    }
    for (extra, flag) in [
        (&["--vti", "v.vti"][..], "--vti"),
        (&["--flipbook", "f.png"][..], "--flipbook"),
        (&["--voxel-size", "2"][..], "--voxel-size"),
    ] {
        let mut args = common.to_vec();
        args.extend_from_slice(&["-o", "a.zarr"]);
        args.extend_from_slice(extra);
        refused(&run(d, &args), flag);
    }
    let left: Vec<PathBuf> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().is_some_and(|n| n != "cache"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn shares_may_give_the_analysis_as_images_or_as_its_ssa() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    analyze_cells(d);
    region_ok(d, BOX, &["-o", "one.zarr", "--chunk", "16"]);
    // Share 0 from the image (analysed into the cache), share 1 from the .ssa of the same
    // analysis: one array, the same as a single run's.
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/cells32.png");
    let image_share = run(
        d,
        &[
            "region",
            fixture.to_str().unwrap(),
            "--periodic",
            BOX,
            "--seed",
            "3",
            "--backend",
            "cpu",
            "-o",
            "two.zarr",
            "--chunk",
            "16",
            "--chunks-of",
            "0/2",
        ],
    );
    assert!(
        image_share.status.success(),
        "{}",
        String::from_utf8_lossy(&image_share.stderr)
    );
    region_ok(
        d,
        BOX,
        &["-o", "two.zarr", "--chunk", "16", "--chunks-of", "1/2"],
    );
    assert!(tree(&d.join("two.zarr")) == tree(&d.join("one.zarr")));
}

#[test]
fn zarr_python_reads_the_array() {
    let Some(python) = std::env::var_os("SOLIDSYNTH_TEST_PYTHON") else {
        // CI sets it (.ci/run's virtual environment); elsewhere the check is optional.
        assert!(
            std::env::var_os("CI").is_none(),
            "CI: SOLIDSYNTH_TEST_PYTHON must name a Python with zarr 3"
        );
        eprintln!("note: SOLIDSYNTH_TEST_PYTHON is not set: the zarr-python check is skipped");
        return;
    };
    let probe = Command::new(&python)
        .args([
            "-c",
            "import sys, zarr; sys.exit(int(zarr.__version__.split('.')[0]) < 3)",
        ])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI: zarr-python 3 is not importable in {python:?}"
        );
        eprintln!("note: zarr-python 3 is not importable in {python:?}: the check is skipped");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    analyze_cells(d);
    region_ok(d, BOX, &["-o", "a.zarr", "--chunk", "16"]);
    region_ok(d, BOX, &["-o", "v.npy"]);
    let script = "import numpy as np, zarr\n\
                  a = zarr.open('a.zarr', mode='r')\n\
                  b = np.load('v.npy')\n\
                  print(a.shape == b.shape, a.dtype == b.dtype, np.array_equal(a[...], b),\n\
                  \x20     list(a.metadata.dimension_names))";
    let out = Command::new(&python)
        .args(["-c", script])
        .current_dir(d)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "zarr-python failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        "True True True ['z', 'y', 'x', 'c']"
    );
}
