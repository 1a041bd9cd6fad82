//! `solidsynth eval` discriminates: volumes that are not solid versions of the exemplar (random
//! shuffles, 2D extrusions) score clearly worse than the floor, while a genuine solid texture
//! (3D Voronoi cells, exemplar = one of its slices) stays near it.

mod common;

use solidsynth::exemplar::{procedural, Image};
use solidsynth::metrics::{evaluate, slices::slice, EvalParams, Report};
use solidsynth::util::hash::SeededRng;
use solidsynth::volume::Volume;

const N: u32 = 64;

fn control() -> (Volume, Image) {
    let v = procedural::cells_3d(N, 100, 5);
    let ex = slice(&procedural::cells_3d(N, 100, 6), 2, 0);
    (v, ex)
}

fn shuffled(ex: &Image) -> Volume {
    let mut v = Volume::new(N, N, N, ex.channels);
    let mut rng = SeededRng::new(1);
    let c = ex.channels as usize;
    for voxel in v.data.chunks_exact_mut(c) {
        let p = rng.below(ex.pixel_count() as u64) as usize;
        voxel.copy_from_slice(&ex.pixels[p * c..(p + 1) * c]);
    }
    v
}

fn extruded(ex: &Image) -> Volume {
    let mut v = Volume::new(ex.width, ex.height, N, ex.channels);
    for z in 0..N {
        for y in 0..ex.height {
            for x in 0..ex.width {
                v.at_mut(x, y, z).copy_from_slice(ex.at(x, y));
            }
        }
    }
    v
}

/// A 3x3x3 box blur: what an over-smoothing synthesis produces.
fn blurred(v: &Volume) -> Volume {
    let mut out = v.clone();
    let c = v.channels as usize;
    for z in 0..v.nz {
        for y in 0..v.ny {
            for x in 0..v.nx {
                let mut acc = vec![0u32; c];
                for (dx, dy, dz) in (0..27).map(|i| (i % 3, i / 3 % 3, i / 9)) {
                    let p = v.at(
                        (x + v.nx + dx - 1) % v.nx,
                        (y + v.ny + dy - 1) % v.ny,
                        (z + v.nz + dz - 1) % v.nz,
                    );
                    acc.iter_mut().zip(p).for_each(|(a, &b)| *a += b as u32);
                }
                out.at_mut(x, y, z)
                    .iter_mut()
                    .zip(&acc)
                    .for_each(|(o, &a)| *o = ((a + 13) / 27) as u8);
            }
        }
    }
    out
}

fn show(name: &str, r: &Report) {
    eprintln!(
        "{name:>9}: worst ratio hist {:.2} coh {:.2} compl {:.2} orient {:.2} sharp {:.2} | floor {:?}",
        r.worst_ratio.histogram, r.worst_ratio.coherence, r.worst_ratio.completeness, r.worst_ratio.orientation,
        r.worst_ratio.sharpness, r.floor
    );
}

#[test]
fn shuffled_and_extruded_volumes_score_clearly_worse_than_a_real_solid() {
    let (solid, ex) = control();
    let params = EvalParams::default();
    let good = evaluate(&solid, std::slice::from_ref(&ex), &params).unwrap();
    let shuf = evaluate(&shuffled(&ex), std::slice::from_ref(&ex), &params).unwrap();
    let extr = evaluate(&extruded(&ex), std::slice::from_ref(&ex), &params).unwrap();
    let blur = evaluate(&blurred(&solid), std::slice::from_ref(&ex), &params).unwrap();
    show("solid", &good);
    show("shuffled", &shuf);
    show("extruded", &extr);
    show("blurred", &blur);
    // A genuine solid texture scores near its floor on every measure.
    assert!(
        good.worst_ratio.max_component() < 2.0,
        "{:?}",
        good.worst_ratio
    );
    // A random shuffle of exemplar pixels: noise, far too sharp, and incoherent patches.
    assert!(shuf.worst_ratio.sharpness > 4.0, "{:?}", shuf.worst_ratio);
    assert!(shuf.worst_ratio.coherence > 1.5, "{:?}", shuf.worst_ratio);
    // The exemplar extruded along z: streaks in the x and y slices, perfect z slices.
    assert!(extr.worst_ratio.orientation > 3.0, "{:?}", extr.worst_ratio);
    assert!(
        extr.per_axis[2].coherence < 1.0
            && extr.per_axis[0].orientation > 3.0 * extr.per_axis[2].orientation
    );
    // Blur shows in sharpness.
    assert!(
        blur.worst_ratio.sharpness > 2.0 * good.worst_ratio.sharpness.max(1.0),
        "{:?}",
        blur.worst_ratio
    );
}

#[test]
fn evaluation_is_deterministic_and_seeded() {
    let (solid, ex) = control();
    let p = EvalParams::default();
    let a =
        serde_json::to_string(&evaluate(&solid, std::slice::from_ref(&ex), &p).unwrap()).unwrap();
    let b =
        serde_json::to_string(&evaluate(&solid, std::slice::from_ref(&ex), &p).unwrap()).unwrap();
    assert_eq!(a, b);
    let other = EvalParams {
        seed: 99,
        ..EvalParams::default()
    };
    let c = serde_json::to_string(&evaluate(&solid, &[ex], &other).unwrap()).unwrap();
    assert_ne!(a, c, "the seed must drive the patch sampling");
}

#[test]
fn volumes_smaller_than_a_patch_are_refused() {
    let ex = common::fixture("cells32.png");
    let err = evaluate(&Volume::new(8, 64, 64, 3), &[ex], &EvalParams::default()).unwrap_err();
    assert!(err.to_string().contains("at least 9"), "{err}");
}

#[test]
fn multiscale_measures_separate_noise_blur_and_extrusion_from_a_real_solid() {
    let (solid, ex) = control();
    let params = EvalParams::default();
    let ratios = |v: &Volume| {
        evaluate(v, std::slice::from_ref(&ex), &params)
            .unwrap()
            .multiscale
            .worst_ratio
    };
    let good = ratios(&solid);
    let shuf = ratios(&shuffled(&ex));
    let extr = ratios(&extruded(&ex));
    let blur = ratios(&blurred(&solid));
    for (name, r) in [
        ("solid", good),
        ("shuffled", shuf),
        ("extruded", extr),
        ("blurred", blur),
    ] {
        eprintln!(
            "{name:>9}: swd {:.2} {:.2} {:.2} spectrum {:.2}",
            r.swd[0], r.swd[1], r.swd[2], r.spectrum
        );
    }
    // A genuine solid stays near its floor at every scale.
    assert!(
        good.swd.iter().all(|&r| r < 2.0) && good.spectrum < 2.0,
        "{good:?}"
    );
    // Noise: the wrong patches at every scale and a flat spectrum.
    assert!(
        shuf.swd[0] > 3.0 * good.swd[0] && shuf.spectrum > 3.0 * good.spectrum,
        "{shuf:?}"
    );
    // Blur: the fine patches and the high frequencies are gone.
    assert!(
        blur.swd[0] > 2.0 * good.swd[0] && blur.spectrum > 2.0 * good.spectrum,
        "{blur:?}"
    );
    // Extrusion: streaks in the x and y slices.
    assert!(extr.swd[0] > 2.0 * good.swd[0], "{extr:?}");
}
