//! Tileable solids: seamless wrap-around, and the same solid in groups as in one piece.

use super::*;

/// A tileable solid wraps around: the difference across the wrap (last slice to first) is like
/// the difference between neighbouring slices inside, unlike in a box of the infinite solid.
#[test]
fn tileable_solids_wrap_around_seamlessly() {
    use solidsynth::backend::Compute;
    use solidsynth::lazy::{Box3, SynthParams, Synthesizer};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = SynthParams {
        seed: 2,
        ..Default::default()
    };
    let mut s = Synthesizer::new(&a, params, &Compute::Cpu).unwrap();
    // 32 and 64 (in one piece, reads wrapping).
    for n in [32u32, 64] {
        let tiled = s.synthesize_tileable(n, &|_, _| {}, false).unwrap().0;
        let boxed = s
            .synthesize(Box3::new([0; 3], [n as i32; 3]), &|_, _| {})
            .unwrap();
        let (t, b) = (seam_ratio(&tiled, n), seam_ratio(&boxed, n));
        eprintln!("{n}^3 seam ratios: tileable {t:.2}, box {b:.2}");
        // Seamless: each axis' wrap differs like an interior step (ratio ~1, 3 summed;
        // measured 3.7 at 32^3), while the box's wrap is a cut through unrelated texture
        // (measured 7.4).
        assert!(
            t < 4.5 && b > 1.5 * t,
            "{n}^3: tileable {t:.2} vs box {b:.2}"
        );
    }
    // Sizes whose coarsest period would not be whole bricks are refused.
    for n in [8, 24, 40, 48, 100] {
        assert!(s.synthesize_tileable(n, &|_, _| {}, false).is_err(), "{n}");
    }
}

/// A tileable solid too large for one buffer is synthesized as boxes of the periodic solid,
/// group by group with their padding: the same voxels as the one-piece synthesis, and so still
/// periodic.
#[test]
fn tileable_solids_in_groups_equal_the_one_piece_solid() {
    use solidsynth::backend::Compute;
    use solidsynth::lazy::{SynthOptions, SynthParams, Synthesizer};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = SynthParams {
        seed: 3,
        ..Default::default()
    };
    let n = 32u32;
    let mut whole = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    let (one_piece, one_piece_triples) = whole.synthesize_tileable(n, &|_, _| {}, true).unwrap();
    assert_eq!(whole.last_stats().unwrap().groups, 1);
    // Groups of 16^3: 8 of them, each with its dependency padding reaching across the period.
    let options = SynthOptions {
        max_group: Some(16),
        shared_coarse_levels: Some(false),
        ..Default::default()
    };
    let mut grouped = Synthesizer::with_options(&a, params, &Compute::Cpu, options).unwrap();
    let (in_groups, group_triples) = grouped.synthesize_tileable(n, &|_, _| {}, true).unwrap();
    assert_eq!(grouped.last_stats().unwrap().groups, 8);
    assert_eq!(in_groups.dims(), one_piece.dims());
    assert!(
        in_groups.data == one_piece.data,
        "grouped tileable solid differs"
    );
    assert!(group_triples == one_piece_triples, "grouped triples differ");
    // The same groups sharing their coarse levels (each synthesized once, as boxes of the
    // periodic solid whose initial level wraps).
    let mut shared = Synthesizer::with_options(
        &a,
        SynthParams {
            seed: 3,
            ..Default::default()
        },
        &Compute::Cpu,
        SynthOptions {
            max_group: Some(16),
            shared_coarse_levels: Some(true),
            ..Default::default()
        },
    )
    .unwrap();
    let (in_shared, shared_triples) = shared.synthesize_tileable(n, &|_, _| {}, true).unwrap();
    assert_eq!(shared.last_stats().unwrap().groups, 8);
    assert!(
        in_shared.data == one_piece.data,
        "shared-level tileable solid differs"
    );
    assert!(
        shared_triples == one_piece_triples,
        "shared-level triples differ"
    );
}

/// Sum over the three axes of (difference across the wrap) / (mean neighbour difference) of a
/// volume of edge `n`.
fn seam_ratio(v: &solidsynth::volume::Volume, n: u32) -> f64 {
    let mut total = 0.0;
    for axis in 0..3 {
        let diff = |k1: u32, k2: u32| {
            let mut s = 0u64;
            for a in 0..n {
                for b in 0..n {
                    let at = |k: u32| {
                        let mut q = [0u32; 3];
                        q[axis] = k;
                        q[(axis + 1) % 3] = a;
                        q[(axis + 2) % 3] = b;
                        v.at(q[0], q[1], q[2]).to_vec()
                    };
                    let (x, y) = (at(k1), at(k2));
                    s += x
                        .iter()
                        .zip(&y)
                        .map(|(a, b)| a.abs_diff(*b) as u64)
                        .sum::<u64>();
                }
            }
            s as f64
        };
        let inner = (0..n - 1).map(|k| diff(k, k + 1)).sum::<f64>() / (n - 1) as f64;
        total += diff(n - 1, 0) / inner;
    }
    total
}
