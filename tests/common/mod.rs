#![allow(dead_code)]
use solidsynth::analysis::{Analysis, AnalysisInput, AnalysisParams};
use solidsynth::backend::Compute;
use solidsynth::exemplar::{decode_image, Border, Image};

pub fn fixture_path(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

pub fn fixture(name: &str) -> Image {
    decode_image(&std::fs::read(fixture_path(name)).unwrap(), name).unwrap()
}

pub fn analyze(images: Vec<Image>, border: Border) -> Analysis {
    let names = (0..images.len()).map(|i| format!("exemplar {i}")).collect();
    let input = AnalysisInput {
        exemplars: images,
        masks: vec![],
        border,
        names,
    };
    solidsynth::lazy::analyze(
        &input,
        &AnalysisParams::default(),
        &Compute::Cpu,
        &|_, _| {},
    )
    .unwrap()
}

/// Crop the top-left `w` x `h` of an image.
pub fn crop(img: &Image, w: u32, h: u32) -> Image {
    let mut out = Image::new(w, h, img.channels);
    for y in 0..h {
        for x in 0..w {
            let i = ((y * w + x) * img.channels) as usize;
            out.pixels[i..i + img.channels as usize].copy_from_slice(img.at(x, y));
        }
    }
    out
}

/// One structured mutation of `valid` (the fuzz tests' shared helper, `tests/fuzz.rs`):
/// truncated, bits flipped, a little-endian word set huge, a section duplicated, or a decimal
/// number made huge.
pub fn mutate(valid: &[u8], rng: &mut solidsynth::util::hash::SeededRng) -> Vec<u8> {
    let mut b = valid.to_vec();
    let at = |rng: &mut solidsynth::util::hash::SeededRng, len: usize| {
        rng.below(len.max(1) as u64) as usize
    };
    match rng.below(5) {
        // Truncated anywhere.
        0 => b.truncate(at(rng, valid.len())),
        // A few bits flipped.
        1 => {
            for _ in 0..1 + rng.below(8) {
                let i = at(rng, b.len());
                if i < b.len() {
                    b[i] ^= 1 << rng.below(8);
                }
            }
        }
        // A little-endian word (a length or count, often) set huge, in the head or anywhere.
        2 => {
            let span = if rng.below(2) == 0 {
                256.min(b.len())
            } else {
                b.len()
            };
            let i = at(rng, span.saturating_sub(4));
            let huge = [u32::MAX, 0x7FFF_FFFF, 0x4000_0000, 1 << 24][rng.below(4) as usize];
            if i + 4 <= b.len() {
                b[i..i + 4].copy_from_slice(&huge.to_le_bytes());
            }
        }
        // A section duplicated in place.
        3 => {
            let i = at(rng, b.len());
            let n = at(rng, (b.len() - i.min(b.len())).min(4096) + 1);
            let section: Vec<u8> = b[i.min(b.len())..(i + n).min(b.len())].to_vec();
            b.splice(i.min(b.len())..i.min(b.len()), section);
        }
        // A decimal number in a text format made huge.
        _ => {
            let digits: Vec<usize> = (0..b.len()).filter(|&i| b[i].is_ascii_digit()).collect();
            if !digits.is_empty() {
                let i = digits[at(rng, digits.len())];
                b.splice(i..i + 1, b"99999999999".iter().copied());
            }
        }
    }
    b
}

/// The voxel at `p` (inside the box `b`) of the volume `v` synthesized for that box.
pub fn voxel_at(v: &solidsynth::volume::Volume, b: solidsynth::lazy::Box3, p: [i32; 3]) -> &[u8] {
    v.at(
        (p[0] - b.lo[0]) as u32,
        (p[1] - b.lo[1]) as u32,
        (p[2] - b.lo[2]) as u32,
    )
}

/// Every pixel of the cut `img` (made by `spec`) equals the voxel it samples in the volume `v`
/// of the box `b`, which holds them all.
pub fn assert_cut_samples_box(
    img: &Image,
    spec: &solidsynth::lazy::cut::CutSpec,
    v: &solidsynth::volume::Volume,
    b: solidsynth::lazy::Box3,
) {
    let channels = img.channels as usize;
    for (k, p) in spec.voxels().unwrap().iter().enumerate() {
        assert!(b.contains(*p), "{spec:?} leaves the box at {p:?}");
        assert_eq!(
            &img.pixels[k * channels..(k + 1) * channels],
            voxel_at(v, b, *p),
            "{spec:?}: pixel {k}"
        );
    }
}

/// A command refused its input: exit code 2, a message mentioning `needle` (a system error as
/// its description, without its number), and `path` not written.
pub fn assert_refused(out: &std::process::Output, needle: &str, path: &std::path::Path) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(needle), "expected {needle:?} in: {err}");
    assert!(!err.contains("(os error"), "{err}");
    assert!(!path.exists(), "{} was written", path.display());
}

/// A 16^3 tileable solid exemplar (lapped textures) of colour waves plus a few hashed speckles (so layers differ).
pub fn lapped_exemplar_volume() -> solidsynth::volume::Volume {
    let n = 16u32;
    let mut v = solidsynth::volume::Volume::new(n, n, n, 3);
    let tau = std::f64::consts::TAU / n as f64;
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let h = solidsynth::util::hash::hash32(x + n * (y + n * z));
                let c = v.at_mut(x, y, z);
                c[0] = (128.0 + 90.0 * (tau * x as f64).sin()) as u8 ^ (h as u8 & 0x1f);
                c[1] = (128.0 + 90.0 * (tau * y as f64).sin()) as u8;
                c[2] = (128.0 + 90.0 * (tau * z as f64).cos()) as u8;
            }
        }
    }
    v
}
