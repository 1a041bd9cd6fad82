//! Kernel `project`: GPU and CPU bit-exact on random and edge-case inputs.

use crate::compare::words_equal;
use solidsynth::analysis::neighbourhood::gather;
use solidsynth::analysis::pca::{self, PcaBasis};
use solidsynth::cpu;
use solidsynth::exemplar::{Border, Image};
use solidsynth::gpu::{self, GpuOptions};
use solidsynth::util::hash::SeededRng;

fn random_image(rng: &mut SeededRng, w: u32, h: u32, c: u32) -> Image {
    let mut img = Image::new(w, h, c);
    img.pixels
        .iter_mut()
        .for_each(|p| *p = rng.below(256) as u8);
    img
}

fn fitted_basis(img: &Image, border: Border, keep: usize) -> PcaBasis {
    let mut vectors = Vec::new();
    for y in 0..img.height {
        for x in 0..img.width {
            gather(img, border, x, y, &mut vectors);
        }
    }
    let d = 25 * img.channels as usize;
    pca::fit(&vectors, d, keep, &vec![1.0; d], 1 << 16).unwrap()
}

fn check(
    ctx: &solidsynth::gpu::GpuContext,
    what: &str,
    img: &Image,
    border: Border,
    basis: &PcaBasis,
) {
    let expected = cpu::project::project(img, border, basis);
    let got = gpu::project::project(ctx, img, border, basis).unwrap();
    words_equal(what, &expected, &got).unwrap();
}

#[test]
fn project_random_inputs_bit_exact() {
    let _serial = crate::serial();
    let Some(ctx) = crate::gpu() else { return };
    let mut rng = SeededRng::new(42);
    for (w, h, c) in [
        (16, 16, 3),
        (37, 19, 1),
        (24, 40, 4),
        (33, 33, 5),
        (64, 48, 3),
    ] {
        for border in [Border::Wrap, Border::Mirror] {
            for keep in [8, 12] {
                let img = random_image(&mut rng, w, h, c);
                let basis = fitted_basis(&img, border, keep);
                check(
                    ctx,
                    &format!("{w}x{h}x{c} {border:?} k={keep}"),
                    &img,
                    border,
                    &basis,
                );
            }
        }
    }
}

#[test]
fn project_edge_cases_bit_exact() {
    let _serial = crate::serial();
    let Some(ctx) = crate::gpu() else { return };
    let mut rng = SeededRng::new(7);
    // Tiny images: mirror and wrap resolve offsets far outside (1- and 2-pixel sides).
    for (w, h) in [(1, 1), (2, 1), (1, 3), (2, 2), (3, 5)] {
        for border in [Border::Wrap, Border::Mirror] {
            let img = random_image(&mut rng, w, h, 3);
            let basis = fitted_basis(&random_image(&mut rng, 16, 16, 3), border, 8);
            check(
                ctx,
                &format!("tiny {w}x{h} {border:?}"),
                &img,
                border,
                &basis,
            );
        }
    }
    // Saturation and the largest weights the overflow bound allows: all-0 and all-255 images,
    // weights of alternating sign at the i32 limit, 5 output dims (a partially filled word).
    let d = 75usize;
    let big = (i32::MAX as i64 / (255 * d as i64)) as i32;
    let weights: Vec<i32> = (0..5 * d)
        .map(|i| if (i / 3) % 2 == 0 { big } else { -big })
        .collect();
    let basis = PcaBasis {
        input_dims: d as u32,
        output_dims: 5,
        shift: 20,
        mean: (0..d).map(|i| (i * 37 % 256) as i32).collect(),
        weights,
        eigenvalues: vec![1.0; d],
    };
    basis.validate().unwrap();
    for fill in [0u8, 255] {
        let mut img = Image::new(16, 16, 3);
        img.pixels.iter_mut().for_each(|p| *p = fill);
        check(
            ctx,
            &format!("saturated fill {fill}"),
            &img,
            Border::Mirror,
            &basis,
        );
    }
    let img = random_image(&mut rng, 20, 20, 3);
    check(ctx, "extreme weights", &img, Border::Wrap, &basis);
}

#[test]
fn project_chunked_dispatch_matches_cpu() {
    let _serial = crate::serial();
    // A storage-binding limit of 1 KiB forces many chunks (each a separate dispatch).
    let opts = GpuOptions {
        max_binding_bytes: Some(1024),
        ..GpuOptions::from_env()
    };
    let Some(ctx) = crate::open(opts) else { return };
    assert_eq!(ctx.max_binding_bytes(), 1024);
    let mut rng = SeededRng::new(3);
    let img = random_image(&mut rng, 45, 31, 3);
    let basis = fitted_basis(&img, Border::Mirror, 12);
    check(&ctx, "chunked", &img, Border::Mirror, &basis);
}

#[test]
fn analysis_is_identical_on_gpu_and_cpu() {
    let _serial = crate::serial();
    let Some(ctx) = crate::gpu() else { return };
    let _ = ctx;
    let img = solidsynth::exemplar::decode_image(
        include_bytes!("../tests/fixtures/cells32.png"),
        "fixture",
    )
    .unwrap();
    let input = solidsynth::analysis::AnalysisInput {
        exemplars: vec![img],
        masks: vec![],
        border: Border::Wrap,
        names: vec!["fixture".into()],
    };
    let params = solidsynth::analysis::AnalysisParams::default();
    let gpu_backend = solidsynth::backend::Compute::open(
        solidsynth::backend::BackendChoice::Gpu,
        &GpuOptions::from_env(),
    )
    .unwrap();
    let on_gpu = solidsynth::lazy::analyze(&input, &params, &gpu_backend, &|_, _| {}).unwrap();
    let on_cpu = solidsynth::lazy::analyze(
        &input,
        &params,
        &solidsynth::backend::Compute::Cpu,
        &|_, _| {},
    )
    .unwrap();
    assert!(solidsynth::io::ssa::to_bytes(&on_gpu) == solidsynth::io::ssa::to_bytes(&on_cpu));
}
