//! Usage balancing (`analysis::balance`): the calibrated penalties spread the correction over the
//! exemplar instead of a few over-used pixels, are part of the analysis, and are off (all zero,
//! the paper's search) with zero rounds.

mod common;

use solidsynth::analysis::balance;
use solidsynth::analysis::{Analysis, AnalysisInput, AnalysisParams};
use solidsynth::backend::Compute;
use solidsynth::exemplar::{Border, Image};
use solidsynth::io::ssa;
use solidsynth::lazy::balance::top_percent_share;
use solidsynth::lazy::{SynthParams, Synthesizer};

fn analyze(image: Image, rounds: u32) -> Analysis {
    let input = AnalysisInput {
        exemplars: vec![image],
        masks: vec![],
        border: Border::Mirror,
        names: vec!["fixture".into()],
    };
    let params = AnalysisParams {
        balance_rounds: rounds,
        ..Default::default()
    };
    solidsynth::lazy::analyze(&input, &params, &Compute::Cpu, &|_, _| {}).unwrap()
}

/// Top-1% usage share of each level (coarsest first) of a tileable solid (another seed than the
/// calibration's, so the penalties are tested on a solid they were not fitted to).
fn usage_shares(a: &Analysis) -> Vec<f64> {
    let params = SynthParams {
        seed: 12345,
        ..Default::default()
    };
    let mut s = Synthesizer::new(a, params, &Compute::Cpu).unwrap();
    s.count_usage();
    s.synthesize_tileable(64, &|_, _| {}, false).unwrap();
    s.take_usage()
        .unwrap()
        .iter()
        .map(|per_exemplar| {
            let all: Vec<u64> = (0..per_exemplar[0].len())
                .map(|i| per_exemplar.iter().map(|c| c[i]).sum())
                .collect();
            top_percent_share(&all)
        })
        .collect()
}

#[test]
fn balancing_spreads_the_correction_over_the_exemplar() {
    let brick = common::fixture("cc0_brick64.png");
    let plain = analyze(brick.clone(), 0);
    let balanced = analyze(brick, balance::DEFAULT_ROUNDS);
    let (before, after) = (usage_shares(&plain), usage_shares(&balanced));
    eprintln!(
        "top-1% usage share per level, coarsest first: plain {before:.3?}, balanced {after:.3?}"
    );
    // Measured on this fixture: without balancing the top 1% of the pixels hold 12-41% of a
    // level's coordinates, with it 6-10%.
    for level in 0..before.len() {
        assert!(
            after[level] < 0.7 * before[level],
            "level {level} (coarsest = 0): top-1% share {:.3} balanced vs {:.3} plain",
            after[level],
            before[level]
        );
    }
}

#[test]
fn zero_rounds_leave_every_penalty_zero_and_rounds_set_some() {
    let marble = common::fixture("marble32.png");
    let plain = analyze(marble.clone(), 0);
    let all_zero = |a: &Analysis| {
        a.exemplars
            .iter()
            .flat_map(|e| &e.levels)
            .all(|l| l.penalty.iter().all(|&p| p == 0))
    };
    assert!(all_zero(&plain));
    let balanced = analyze(marble, 2);
    assert!(!all_zero(&balanced));
    for l in &balanced.exemplars[0].levels {
        assert_eq!(l.penalty.len(), l.image.pixel_count());
    }
}

#[test]
fn penalties_travel_in_the_ssa_file() {
    let a = analyze(common::fixture("marble32.png"), 1);
    let back = ssa::from_bytes(&ssa::to_bytes(&a)).unwrap();
    assert_eq!(back, a);
    assert_eq!(back.params.balance_rounds, 1);
}
