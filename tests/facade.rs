//! The library facade (`solidsynth::Solid`): the same settings give the same bytes as the
//! command line; bad input is refused with the flag's name and nothing written; requests can
//! be cancelled; the analysis cache checks what it loads.

mod common;

use solidsynth::solid::cache::{cache_key, AnalysisCache, Cached};
use solidsynth::solid::ExemplarInput;
use solidsynth::util::cancel::CancelToken;
use solidsynth::{Box3, Error, Solid};
use std::process::Command;

fn fixture_path(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// `solidsynth region` with these arguments (the CPU backend, a cache of its own), loaded.
fn cli_region(input: Option<&std::path::Path>, b: &str, seed: &str) -> solidsynth::volume::Volume {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.nrrd");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_solidsynth"));
    cmd.env("SOLIDSYNTH_CACHE_DIR", dir.path().join("cache"))
        .env("SOLIDSYNTH_LOG", "warn");
    cmd.arg("region");
    if let Some(p) = input {
        cmd.arg(p);
    }
    let o = cmd
        .args(["--box", b, "--seed", seed, "--backend", "cpu", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    solidsynth::io::nrrd::load(&out).unwrap()
}

#[test]
fn the_facade_gives_the_command_lines_bytes() {
    // The built-in exemplar (three images in the paper's frame, feature masks, balancing).
    let b = Box3::new([-5, 3, -9], [11, 12, 4]);
    let lib = Solid::builder()
        .seed(6)
        .cpu()
        .build()
        .unwrap()
        .region(b)
        .unwrap();
    let cli = cli_region(None, "-5,3,-9,11,12,4", "6");
    assert_eq!(
        (lib.nx, lib.ny, lib.nz, lib.channels),
        (cli.nx, cli.ny, cli.nz, cli.channels)
    );
    assert_eq!(lib.data, cli.data, "built-in exemplar");
    // A fixture image, not periodic (mirrored borders).
    let image = common::fixture("marble32.png");
    let b = Box3::new([0, 0, 0], [12, 10, 8]);
    let mut solid = Solid::builder()
        .exemplar(image)
        .seed(2)
        .cpu()
        .build()
        .unwrap();
    let lib = solid.region(b).unwrap();
    let cli = cli_region(Some(&fixture_path("marble32.png")), "0,0,0,12,10,8", "2");
    assert_eq!(lib.data, cli.data, "marble32.png");
    // Into a caller's buffer, and in slabs: the same bytes.
    let mut buffer = vec![0u8; lib.data.len()];
    solid.region_into(b, &mut buffer).unwrap();
    assert_eq!(buffer, lib.data);
    assert!(solid.region_into(b, &mut buffer[1..]).is_err());
}

/// The error is the caller's, names `needle`, and nothing came back.
fn refused<T: std::fmt::Debug>(r: solidsynth::Result<T>, needle: &str) {
    let e = r.expect_err("refused");
    assert!(e.is_user_error(), "{e}");
    assert!(e.to_string().contains(needle), "'{needle}' not in: {e}");
}

#[test]
fn bad_input_through_the_facade_is_refused_by_name() {
    let tiny = solidsynth::exemplar::Image::new(4, 4, 3);
    refused(Solid::builder().exemplar(tiny).cpu().build(), "exemplar");
    let empty = solidsynth::exemplar::Image::new(0, 0, 3);
    refused(Solid::builder().exemplar(empty).cpu().build(), "exemplar");
    let marble = common::fixture("marble32.png");
    let cells = common::crop(&common::fixture("cells32.png"), 32, 24);
    refused(
        Solid::builder()
            .exemplars(marble.clone(), cells, marble.clone())
            .cpu()
            .build(),
        "same size",
    );
    refused(Solid::builder().jitter(-1.0).cpu().build(), "--jitter");
    refused(
        Solid::builder()
            .feature_masks(solidsynth::solid::FeatureMasks::None)
            .feature_weight(2.0)
            .cpu()
            .build(),
        "--feature-weight",
    );
    let mut solid = Solid::builder()
        .exemplar(marble)
        .balance(0, 1.0)
        .cpu()
        .build()
        .unwrap();
    refused(
        solid.region(Box3::new([0, 0, 0], [0, 4, 4])),
        "--box 0,0,0,0,4,4",
    );
    refused(solid.region(Box3::new([3, 0, 0], [1, 4, 4])), "--box");
    // Beyond any machine's memory: refused before allocating, naming the estimate.
    refused(
        solid.region(Box3::new([0; 3], [1 << 20; 3])),
        "TiB of memory",
    );
    refused(solid.tileable(48), "multiple of 32");
    // A device lacking a limit the kernels need: the limit is named.
    let mut limits = solidsynth::gpu::context::required_limits();
    assert_eq!(solidsynth::gpu::context::missing_limit(&limits), None);
    limits.max_storage_buffers_per_shader_stage = 4;
    let missing = solidsynth::gpu::context::missing_limit(&limits).unwrap();
    assert!(
        missing.contains("max_storage_buffers_per_shader_stage"),
        "{missing}"
    );
}

#[test]
fn a_cancelled_request_stops_with_a_typed_error() {
    // One analysis, two solids of it, each with its own token, in groups of 8 voxels.
    let builder = Solid::builder()
        .exemplar(common::fixture("cells32.png"))
        .periodic(true)
        .balance(0, 1.0)
        .max_group(Some(8))
        .cpu();
    let analysis = builder.analyze().unwrap();
    let solid_with = |token: CancelToken| {
        builder
            .clone()
            .shared_analysis(analysis.clone())
            .exemplar_input(ExemplarInput::default())
            .cancel(token)
            .build()
            .unwrap()
    };
    let token = CancelToken::new();
    let mut solid = solid_with(token.clone());
    let b = Box3::new([0; 3], [24; 3]);
    let whole = solid.region(b).unwrap();
    token.cancel();
    assert!(matches!(solid.region(b), Err(Error::Cancelled)));
    // Cancelled part way: the sink saw some slabs, then the request stopped.
    let token = CancelToken::new();
    let stop = token.clone();
    let mut solid = solid_with(token);
    let mut slabs = 0;
    let r = solid.region_slabs(b, false, |slab| {
        slabs += 1;
        assert_eq!(slab.volume.data[..], whole.data[..slab.volume.data.len()]);
        stop.cancel();
        Ok(())
    });
    assert!(matches!(r, Err(Error::Cancelled)), "{r:?}");
    assert_eq!(slabs, 1);
}

/// A small periodic exemplar without balancing (a fast analysis) and its cache key.
fn cells_cache_input() -> (ExemplarInput, u128) {
    let input = ExemplarInput {
        images: vec![common::fixture("cells32.png")],
        periodic: true,
        balance_rounds: 0,
        ..Default::default()
    };
    let (analysis_input, params) = input.analysis_input().unwrap();
    let key = cache_key(&analysis_input, &params);
    (input, key)
}

#[test]
fn the_cache_uses_only_what_belongs_to_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let cache = AnalysisCache::at(dir.path());
    let (input, key) = cells_cache_input();
    // A different input (another border) has another key.
    let mirrored = ExemplarInput {
        periodic: false,
        ..input.clone()
    };
    let (other_input, other_params) = mirrored.analysis_input().unwrap();
    assert_ne!(key, cache_key(&other_input, &other_params));
    assert!(matches!(cache.load(key), Cached::Miss));
    let solid = Solid::builder()
        .exemplar_input(input.clone())
        .cache(Some(cache.clone()))
        .cpu();
    let first = solid.analyze().unwrap();
    assert!(matches!(cache.load(key), Cached::Hit(_)));
    let second = solid.analyze().unwrap();
    assert_eq!(
        solidsynth::io::ssa::to_bytes(&first),
        solidsynth::io::ssa::to_bytes(&second)
    );
    // Another input's file under this key: refused, analysed again, replaced.
    let path = cache.path(key);
    let good = std::fs::read(&path).unwrap();
    cache.store(key ^ 1, &first).unwrap();
    std::fs::copy(cache.path(key ^ 1), &path).unwrap();
    assert!(matches!(cache.load(key), Cached::Invalid(p) if p.contains("another input")));
    let again = solid.analyze().unwrap();
    assert_eq!(
        solidsynth::io::ssa::to_bytes(&again),
        solidsynth::io::ssa::to_bytes(&first)
    );
    assert_eq!(
        std::fs::read(&path).unwrap(),
        good,
        "replaced by the right analysis"
    );
    // Truncated, or a flipped bit: refused too.
    std::fs::write(&path, &good[..good.len() / 2]).unwrap();
    assert!(matches!(cache.load(key), Cached::Invalid(_)));
    let mut flipped = good.clone();
    let at = flipped.len() - 100;
    flipped[at] ^= 4;
    std::fs::write(&path, &flipped).unwrap();
    assert!(matches!(cache.load(key), Cached::Invalid(_)));
}

/// Two writers of the same analysis at once (two processes analysing one image) leave one
/// whole file: each write is a temporary renamed into place.
#[test]
fn concurrent_cache_writers_leave_one_whole_file() {
    let dir = tempfile::tempdir().unwrap();
    let cache = AnalysisCache::at(dir.path());
    let (input, key) = cells_cache_input();
    let analysis = Solid::builder()
        .exemplar_input(input)
        .cpu()
        .analyze()
        .unwrap();
    std::thread::scope(|s| {
        for _ in 0..4 {
            s.spawn(|| {
                for _ in 0..10 {
                    cache.store(key, &analysis).unwrap();
                    assert!(
                        matches!(cache.load(key), Cached::Hit(_)),
                        "a reader saw a partial file"
                    );
                }
            });
        }
    });
    let files: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(files.len(), 1, "one file, no temporaries left");
    assert!(matches!(cache.load(key), Cached::Hit(_)));
}
