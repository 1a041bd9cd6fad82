//! Structured mutations of a valid file for every parser the project owns (NRRD raw and gzip,
//! `.ssa`, `.gsolid`, PTM and its light files, `.lst`, OBJ, PLY and gzipped PLY, glTF, the
//! constraints and strokes JSON): truncations, bit flips, length-like words set to huge values,
//! duplicated sections. Each must give a clean error or a value, never a panic, and no single
//! allocation above [`ALLOCATION_BOUND`] (a length field claiming gigabytes must be checked
//! against the file's size before anything is allocated).
//! `SOLIDSYNTH_FUZZ_CASES` sets the cases per parser (default 1500), with a fixed seed.
//!
//! One test in this binary, so the allocator's record is the parsers' alone.

mod common;

use solidsynth::util::hash::SeededRng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The largest allocation a parser may make for an input of a few MB.
const ALLOCATION_BOUND: usize = 256 << 20;

struct Recording;
static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, recording the largest request.
unsafe impl GlobalAlloc for Recording {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Recording = Recording;

/// Mutations of `valid` through `parse`: no panic, no allocation over the bound. Returns how
/// many were accepted (a mutation may still be a valid file).
fn fuzz<T, E>(name: &str, valid: &[u8], parse: impl Fn(&[u8]) -> Result<T, E>) -> usize {
    let cases: usize = std::env::var("SOLIDSYNTH_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1500);
    assert!(parse(valid).is_ok(), "{name}: the valid sample parses");
    let mut rng = SeededRng::new(0xF022 ^ name.len() as u64);
    let mut accepted = 0;
    for case in 0..cases {
        let input = common::mutate(valid, &mut rng);
        LARGEST.store(0, Ordering::Relaxed);
        let outcome =
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| parse(&input).is_ok()));
        let largest = LARGEST.load(Ordering::Relaxed);
        match outcome {
            Ok(ok) => accepted += ok as usize,
            Err(_) => panic!(
                "{name}: case {case} panicked (input of {} bytes)",
                input.len()
            ),
        }
        assert!(
            largest <= ALLOCATION_BOUND,
            "{name}: case {case} allocated {largest} bytes at once (input of {} bytes)",
            input.len()
        );
    }
    eprintln!("{name}: {cases} mutations, {accepted} accepted as valid");
    accepted
}

#[test]
fn every_parser_survives_structured_mutations() {
    // The helper catches what it is for: a parser that trusts a length word (it allocates what
    // the word says) and one that panics on a short input.
    let trusting = |b: &[u8]| -> Result<usize, String> {
        let claimed = u32::from_le_bytes(b.get(..4).ok_or("short")?.try_into().unwrap()) as usize;
        Ok(Vec::<u8>::with_capacity(claimed).capacity())
    };
    let caught = std::panic::catch_unwind(|| fuzz("trusting", &[8, 0, 0, 0, 1, 2], trusting));
    assert!(
        caught.is_err(),
        "an allocation of a claimed length goes unnoticed"
    );
    let fragile = |b: &[u8]| -> Result<u8, String> { Ok(b[5]) };
    let caught = std::panic::catch_unwind(|| fuzz("fragile", &[1, 2, 3, 4, 5, 6], fragile));
    assert!(caught.is_err(), "a panic goes unnoticed");

    // NRRD.
    let dir = tempfile::tempdir().unwrap();
    let mut volume = solidsynth::volume::Volume::new(6, 5, 4, 3);
    volume
        .data
        .iter_mut()
        .enumerate()
        .for_each(|(i, v)| *v = i as u8);
    let nrrd_path = dir.path().join("v.nrrd");
    solidsynth::io::nrrd::save(&volume, &nrrd_path).unwrap();
    fuzz(
        "nrrd",
        &std::fs::read(&nrrd_path).unwrap(),
        solidsynth::io::nrrd::parse,
    );
    let gzip_nrrd = [
        solidsynth::io::nrrd::header_encoded(volume.dims(), volume.channels, true).into_bytes(),
        solidsynth::io::nrrd::gzip_bytes(&volume.data),
    ]
    .concat();
    fuzz("nrrd gzip", &gzip_nrrd, solidsynth::io::nrrd::parse);
    // .ssa.
    let analysis = common::analyze(
        vec![common::crop(&common::fixture("cells32.png"), 20, 20)],
        solidsynth::exemplar::Border::Wrap,
    );
    let ssa = solidsynth::io::ssa::to_bytes(&analysis);
    fuzz("ssa", &ssa, solidsynth::io::ssa::from_bytes);
    // .gsolid.
    let solid = solidsynth::gradient::render::random_solid(13, 3, 5).unwrap();
    for encoding in [
        solidsynth::gradient::format::Encoding::U8,
        solidsynth::gradient::format::Encoding::F32,
    ] {
        let bytes = solidsynth::gradient::format::to_bytes(&solid, encoding);
        fuzz("gsolid", &bytes, |b| {
            solidsynth::gradient::format::from_bytes(b, "fuzz")
        });
    }
    // PTM.
    let capture = solidsynth::ptm::capture::synthetic(16, 8, 3);
    let ptm =
        solidsynth::ptm::fit::fit(&capture, solidsynth::ptm::PtmFormat::Lrgb, "fuzz").unwrap();
    fuzz(
        "ptm",
        &solidsynth::ptm::format::to_bytes(&ptm),
        solidsynth::ptm::format::from_bytes,
    );
    // .lst: a small lapped model.
    let lst = lapped_model_bytes();
    fuzz("lst", &lst, solidsynth::lapped::model::LstModel::parse);
    // OBJ.
    let obj = solidsynth::lapped::shapes::obj_text(&solidsynth::lapped::shapes::sphere(8, 4));
    fuzz("obj", obj.as_bytes(), |b| {
        solidsynth::mesh::parse_obj(b, "fuzz")
    });
    // PLY, ASCII and binary: the crate's parser and our reading of its elements (a count field
    // set huge must not be allocated before the data runs out).
    let ply_ascii =
        b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
        property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n4 0 1 3 2\n";
    fuzz("ply", ply_ascii, |b| solidsynth::mesh::parse_ply(b, "fuzz"));
    let mut ply_binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\n\
        property float x\nproperty float y\nproperty float z\nelement face 2\n\
        property list uchar uint vertex_indices\nend_header\n"
        .to_vec();
    for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]] {
        ply_binary.extend(v.iter().flat_map(|c| c.to_le_bytes()));
    }
    for face in [&[0u32, 1, 2][..], &[0, 1, 3, 2]] {
        ply_binary.push(face.len() as u8);
        ply_binary.extend(face.iter().flat_map(|i| i.to_le_bytes()));
    }
    fuzz("ply binary", &ply_binary, |b| {
        solidsynth::mesh::parse_ply(b, "fuzz")
    });
    // Gzipped: the header inflated first, the stream then bounded by it.
    let ply_gz = solidsynth::io::nrrd::gzip_bytes(&ply_binary);
    fuzz("ply.gz", &ply_gz, |b| {
        solidsynth::mesh::parse_ply_gz(b, "fuzz")
    });
    // glTF in: the crate's parser and our reading of its primitives, from a .glb written here
    // (NPY, TIFF and KTX2 are only written, by the tool).
    let sphere = solidsynth::lapped::shapes::sphere(6, 3);
    let atlas = solidsynth::mesh::bake::Atlas::new(sphere.triangles.len(), 2, 0).unwrap();
    let glb = solidsynth::mesh::glb::glb_bytes(&sphere, &atlas, &[0u8; 16]).unwrap();
    fuzz("glb", &glb, |b| {
        solidsynth::mesh::gltf_in::parse_gltf(b, "fuzz", None)
    });
    // PTM light files: the `.lp` text and the JSON form.
    fuzz(
        "lights lp",
        b"3\na.png 0 0 1\nb.png 1 0 1\nc.png 0 -1 1\n",
        |b| {
            let text = std::str::from_utf8(b).map_err(|e| e.to_string())?;
            solidsynth::ptm::capture::parse_lights(text, "fuzz", false).map_err(|e| e.to_string())
        },
    );
    let lights_json =
        br#"{"lights": [{"file": "a.png", "lu": 0.1, "lv": 0.2}, {"file": "b.png", "direction": [0, 1, 1]}]}"#;
    fuzz("lights json", lights_json, |b| {
        let text = std::str::from_utf8(b).map_err(|e| e.to_string())?;
        solidsynth::ptm::capture::parse_lights(text, "fuzz", true).map_err(|e| e.to_string())
    });
    // Constraints and strokes JSON.
    let constraints = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/lapped/kiwi.json"
    ))
    .unwrap();
    fuzz("constraints", &constraints, |b| {
        solidsynth::lapped::field::Constraints::parse(b, "fuzz")
    });
    let strokes = br#"{"strokes": [{"position": [8, 8, 8], "strength": 1.0}, {"position": [1, 2, 3], "strength": 0.5}]}"#;
    fuzz("strokes", strokes, |b| {
        let text = std::str::from_utf8(b).map_err(|e| e.to_string())?;
        solidsynth::gradient::edit::parse_strokes(text, "fuzz").map_err(|e| e.to_string())
    });
}

fn lapped_model_bytes() -> Vec<u8> {
    use solidsynth::lapped::{self, exemplar::SolidExemplar, field::Constraints};
    let mut cube = solidsynth::volume::Volume::new(8, 8, 8, 4);
    cube.data
        .iter_mut()
        .enumerate()
        .for_each(|(i, v)| *v = (i * 7) as u8);
    let exemplar = SolidExemplar::from_volume(&cube, "cube").unwrap();
    let sphere = lapped::shapes::sphere(10, 5);
    let constraints = Constraints::isotropic();
    let inputs = lapped::FillInputs {
        mesh: &sphere,
        mesh_name: "sphere",
        exemplar,
        exemplar_source: "cube",
        constraints: &constraints,
        constraints_name: "isotropic",
    };
    let opts = lapped::FillOptions {
        resolution: 3,
        ..Default::default()
    };
    lapped::build(inputs, &opts, &|_, _| {})
        .unwrap()
        .0
        .to_bytes()
}
