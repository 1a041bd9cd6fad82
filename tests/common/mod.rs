#![allow(dead_code)]
use solidsynth::analysis::{Analysis, AnalysisInput, AnalysisParams};
use solidsynth::backend::Compute;
use solidsynth::exemplar::{decode_image, Border, Image};

pub fn fixture(name: &str) -> Image {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name);
    decode_image(&std::fs::read(&path).unwrap(), name).unwrap()
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
