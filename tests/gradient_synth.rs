//! Direct gradient-solid synthesis (paper section 4): determinism, tileability, and that the
//! result is a texture (not collapsed to a flat colour) resembling its exemplar.

use solidsynth::backend::Compute;
use solidsynth::exemplar::procedural::cobblestone;
use solidsynth::gradient::synth::{synthesize, GradientSynthParams, PeriodicSolid, SliceSearch};
use solidsynth::gradient::vectorize::render;

fn run(params: &GradientSynthParams) -> PeriodicSolid {
    let exemplar = cobblestone(48, 9, 3);
    synthesize(&exemplar, params, &Compute::Cpu, &|_, _| {})
        .unwrap()
        .0
}

fn small() -> GradientSynthParams {
    GradientSynthParams {
        seed: 11,
        size: 24,
        iterations: 2,
        ..Default::default()
    }
}

#[test]
fn same_seed_same_bits_at_any_thread_count_and_another_seed_differs() {
    let params = small();
    let two = run(&params);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| run(&params));
    assert_eq!(one, two);
    let other = run(&GradientSynthParams { seed: 12, ..params });
    assert_ne!(other, two);
}

#[test]
fn the_solid_is_textured_like_its_exemplar_and_tiles() {
    let exemplar = cobblestone(48, 9, 3);
    for search in [
        SliceSearch::Crossbar { n1: 20, n2: 50 },
        SliceSearch::CrossbarNearest { n1: 20, n2: 50 },
        SliceSearch::Independent,
    ] {
        let params = GradientSynthParams { search, ..small() };
        let (periodic, report) = synthesize(&exemplar, &params, &Compute::Cpu, &|_, _| {}).unwrap();
        assert_eq!(report.levels.len(), 3);
        assert!(report.levels.iter().all(|l| l.refitted > 0.9), "{report:?}");
        let solid = periodic.to_gradient_solid().unwrap();
        assert_eq!(solid.dims, [7, 7, 7]);
        // Tileable: the last face repeats the first.
        for y in 0..7 {
            for c in 0..3 {
                assert_eq!(solid.at([6, y, 2], c), solid.at([0, y, 2], c));
            }
        }
        // Not collapsed: the rendered colours spread like the exemplar's, and its mean is close.
        let v = render(&solid, [24, 24, 24]);
        let stats = |px: &[u8]| {
            let n = px.len() as f64;
            let mean = px.iter().map(|&x| x as f64).sum::<f64>() / n;
            let sd = (px.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n).sqrt();
            (mean, sd)
        };
        let (em, es) = stats(&exemplar.with_channels(3).pixels);
        let (vm, vs) = stats(&v.data);
        assert!((em - vm).abs() < 0.15 * em, "mean {vm} vs exemplar {em}");
        assert!(vs > 0.6 * es, "spread {vs} vs exemplar {es} ({search:?})");
    }
}

#[test]
fn bad_parameters_are_refused() {
    let exemplar = cobblestone(48, 9, 3);
    for params in [
        GradientSynthParams { size: 8, ..small() },
        GradientSynthParams {
            iterations: 0,
            ..small()
        },
        GradientSynthParams {
            clusters: 40,
            ..small()
        },
    ] {
        let e = synthesize(&exemplar, &params, &Compute::Cpu, &|_, _| {}).unwrap_err();
        assert!(e.is_user_error(), "{e}");
    }
    // An exemplar smaller than the coarsest patch span (33 pixels).
    let tiny = cobblestone(24, 4, 1);
    let e = synthesize(&tiny, &small(), &Compute::Cpu, &|_, _| {}).unwrap_err();
    assert!(e.to_string().contains("33x33"), "{e}");
}

#[test]
fn the_final_optimization_fits_the_last_samples_better() {
    let exemplar = cobblestone(48, 9, 3);
    let params = GradientSynthParams {
        optimize_iterations: 15,
        ..small()
    };
    let (_, report) = synthesize(&exemplar, &params, &Compute::Cpu, &|_, _| {}).unwrap();
    let (before, after) = report.optimize_rms;
    assert!(after < 0.8 * before, "eq. 3 RMS {before} -> {after}");
    // Its samples are dense voxels: refused above 256^3.
    let big = GradientSynthParams {
        size: 300,
        ..params
    };
    assert!(big.validate().unwrap_err().is_user_error());
}

#[test]
fn a_direction_field_turns_the_slices_deterministically() {
    use solidsynth::gradient::synth::Field;
    let turned = GradientSynthParams {
        field: Field::Cylinder([0.0, 1.0, 1.0]),
        ..small()
    };
    let a = run(&turned);
    assert_eq!(a, run(&turned));
    assert_ne!(a, run(&small()));
    assert!(a.value_spread() > 20.0, "{}", a.value_spread());
}

#[test]
fn two_matched_slices_leave_the_z_slice_free_and_still_texture_the_solid() {
    let two = GradientSynthParams {
        matched_slices: 2,
        ..small()
    };
    let a = run(&two);
    assert_eq!(a, run(&two));
    assert_ne!(a, run(&small()));
    assert!(a.value_spread() > 20.0, "{}", a.value_spread());
    let bad = GradientSynthParams {
        matched_slices: 1,
        ..small()
    };
    assert!(bad.validate().unwrap_err().is_user_error());
}

/// Region separation (`gradient synth --mask`, paper 3.2, 4.2.2, 4.3) on red discs over a blue
/// ground.
mod regions {
    use super::*;
    use solidsynth::cpu::tricubic_eval::{tricubic_eval, Query};
    use solidsynth::exemplar::procedural::discs;
    use solidsynth::gradient::format::Encoding;
    use solidsynth::gradient::regions::{Blend, RegionSolid};
    use solidsynth::gradient::synth::{synthesize_regions, MaskedExemplar};
    use solidsynth::gradient::GradientSolid;

    const RED: [f64; 3] = [220.0, 40.0, 30.0];
    const BLUE: [f64; 3] = [30.0, 60.0, 200.0];

    fn exemplar() -> (solidsynth::exemplar::Image, MaskedExemplar) {
        let (img, mask) = discs(48, 9, 6.5, 5);
        let masked = MaskedExemplar::new(&img, &mask, "--mask m.png").unwrap();
        (img, masked)
    }

    fn params() -> GradientSynthParams {
        GradientSynthParams {
            seed: 3,
            size: 24,
            iterations: 2,
            ..Default::default()
        }
    }

    fn dist(p: &[u8], c: [f64; 3]) -> f64 {
        p.iter()
            .zip(c)
            .map(|(&v, c)| (v as f64 - c).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    /// Fraction of voxels whose colour is far from both region colours (a blurred boundary).
    fn far_from_both(v: &solidsynth::volume::Volume) -> f64 {
        let far = v
            .data
            .chunks_exact(3)
            .filter(|p| dist(p, RED) > 90.0 && dist(p, BLUE) > 90.0)
            .count();
        far as f64 / (v.data.len() / 3) as f64
    }

    fn faces_equal(s: &GradientSolid) {
        let m = s.dims[0] - 1;
        for a in 0..m + 1 {
            for b in 0..m + 1 {
                for c in 0..s.channels {
                    assert_eq!(s.at([m, a, b], c), s.at([0, a, b], c));
                    assert_eq!(s.at([a, m, b], c), s.at([a, 0, b], c));
                    assert_eq!(s.at([a, b, m], c), s.at([a, b, 0], c));
                }
            }
        }
    }

    #[test]
    fn a_mask_keeps_each_region_its_colour_and_the_boundary_sharp_and_tiles() {
        let (img, masked) = exemplar();
        let (rs, report) = synthesize_regions(&masked, &params(), &Compute::Cpu, &|_, _| {})
            .expect("masked synthesis");
        let r = report.regions.clone().unwrap();
        assert_eq!(rs.distance.dims, [7, 7, 7]);
        assert!(r.split_points > 0 && r.split_points < r.points, "{r:?}");
        assert!(
            (r.positive_fraction - r.exemplar_positive_fraction).abs() < 0.15,
            "{r:?}"
        );
        // Tileable: every grid's last faces repeat its first, and so do the split flags.
        for s in [&rs.distance, &rs.positive, &rs.negative] {
            faces_equal(s);
        }
        let n = 24u32;
        let at = |x: u32, y: u32, z: u32| ((z * 7 + y) * 7 + x) as usize;
        for a in 0..7 {
            for b in 0..7 {
                assert_eq!(rs.split[at(6, a, b)], rs.split[at(0, a, b)]);
                assert_eq!(rs.split[at(a, b, 6)], rs.split[at(a, b, 0)]);
            }
        }
        // Each side of the stored distance has its region's colour.
        let v = rs.render([n; 3], &Compute::Cpu, Blend::Exact).unwrap();
        let d = tricubic_eval(&rs.distance, &Query::volume([n; 3]));
        let (mut pos, mut pos_red, mut neg, mut neg_blue) = (0, 0, 0, 0);
        for (p, &dv) in v.data.chunks_exact(3).zip(&d) {
            if dv >= 0.5 {
                pos += 1;
                pos_red += (dist(p, RED) < dist(p, BLUE)) as u32;
            } else if dv <= -0.5 {
                neg += 1;
                neg_blue += (dist(p, BLUE) < dist(p, RED)) as u32;
            }
        }
        let (red_share, blue_share) = (pos_red as f64 / pos as f64, neg_blue as f64 / neg as f64);
        assert!(
            red_share > 0.9 && blue_share > 0.9,
            "positive side red {red_share}, negative side blue {blue_share}"
        );
        // Sharper than the same synthesis without the mask: fewer voxels far from both colours.
        let (plain, _) = synthesize(&img, &params(), &Compute::Cpu, &|_, _| {}).unwrap();
        let plain = render(&plain.to_gradient_solid().unwrap(), [n; 3]);
        let (with, without) = (far_from_both(&v), far_from_both(&plain));
        eprintln!(
            "far from both colours: {with:.4} with the mask, {without:.4} without; positive side \
             red {red_share:.3}, negative side blue {blue_share:.3}; {r:?}"
        );
        assert!(
            with < 0.5 * without,
            "with the mask {with}, without {without}"
        );
        // The file round-trips.
        let bytes = rs.to_bytes(Encoding::F32);
        assert_eq!(RegionSolid::from_bytes(&bytes, "t").unwrap(), rs);
    }

    #[test]
    fn masked_synthesis_is_deterministic_across_thread_counts() {
        let (_, masked) = exemplar();
        let p = GradientSynthParams {
            size: 16,
            optimize_iterations: 5,
            ..params()
        };
        let go = || {
            let (rs, report) = synthesize_regions(&masked, &p, &Compute::Cpu, &|_, _| {}).unwrap();
            let (before, after) = report.optimize_rms;
            assert!(after < before, "eq. 3 RMS {before} -> {after}");
            rs.to_bytes(Encoding::F32)
        };
        let two = go();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(go);
        assert!(one == two, "thread counts differ");
    }

    #[test]
    fn bad_masks_and_sizes_are_refused() {
        let (img, mask) = discs(48, 9, 6.5, 5);
        let small = solidsynth::exemplar::Image::new(40, 48, 1);
        let e = MaskedExemplar::new(&img, &small, "--mask m.png").unwrap_err();
        assert!(e.is_user_error() && e.to_string().contains("--mask"), "{e}");
        let mut full = mask.clone();
        full.pixels.iter_mut().for_each(|p| *p = 200);
        let e = MaskedExemplar::new(&img, &full, "--mask m.png").unwrap_err();
        assert!(
            e.is_user_error() && e.to_string().contains("all inside"),
            "{e}"
        );
        let masked = MaskedExemplar::new(&img, &mask, "--mask m.png").unwrap();
        let big = GradientSynthParams {
            size: 260,
            ..params()
        };
        assert!(big.validate().is_ok());
        let e = synthesize_regions(&masked, &big, &Compute::Cpu, &|_, _| {}).unwrap_err();
        assert!(e.is_user_error() && e.to_string().contains("--mask"), "{e}");
    }
}
