//! Relightable PTM synthesis: fitting, the .ptm format (round trips, a seeded fuzz of the reader),
//! the Legendre basis, the exact projection search against brute force, quilting, relighting, and
//! the `solidsynth ptm` commands (including bad input: exit 2, nothing written). The shared helpers
//! are here, the tests in one module per part.

mod commands;
mod fitting;
mod ptm_files;
mod quilting;
mod searches;

#[path = "../common/mod.rs"]
mod common;

use common::assert_refused;
use solidsynth::cpu::ptm_relight::{ptm_relight, Lighting};
use solidsynth::ptm::capture::{self, Capture, Light};
use solidsynth::ptm::quilt::{self, Boundary, QuiltParams, SearchMethod};
use solidsynth::ptm::search::{self, FeatureImage, SearchStats, Searcher, Shape, Tolerance};
use solidsynth::ptm::{fit, format, legendre, Ptm, PtmFormat};
use solidsynth::util::hash::SeededRng;
use std::path::Path;
use std::process::{Command, Output};

fn source(size: u32, format: PtmFormat, seed: u64) -> Ptm {
    let cap = capture::synthetic(size, 16, seed);
    fit::fit(&cap, format, "test capture").unwrap()
}

/// A query image: quilting-like states made of random source pixels and another surface.
fn query_image(src: &FeatureImage, format: PtmFormat, w: u32, h: u32, seed: u64) -> FeatureImage {
    let other = search::features(&source(w.max(h), format, seed));
    let mut q = FeatureImage::new(w, h, src.dims);
    let mut rng = SeededRng::new(seed);
    for y in 0..h {
        for x in 0..w {
            let v: Vec<i32> = if rng.below(3) == 0 {
                let (sx, sy) = (
                    rng.below(src.width as u64) as u32,
                    rng.below(src.height as u64) as u32,
                );
                src.run(sx, sy, 1).to_vec()
            } else {
                other.run(x, y, 1).to_vec()
            };
            q.pixel_mut(x, y).copy_from_slice(&v);
        }
    }
    q
}

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_solidsynth"));
    c.env("SOLIDSYNTH_LOG", "warn");
    c
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}
