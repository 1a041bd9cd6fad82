//! Usage balancing: a static, per-pixel penalty on exemplar pixels that the correction over-uses.
//!
//! Why. Measured on photographs (`stone_brick`, 64^3): without it, the correction at the second
//! synthesized level collapses onto a handful of flat, mid-tone exemplar pixels whose triples are
//! mutually consistent (the top 1% of pixels held 43% of all voxel coordinates). Such a region
//! tiles itself into a bland solid that matches every neighbourhood a little, so the slices lose
//! their contrast, dark features and histogram (sharpness 19x the exemplar's floor). This is the
//! washing-out that Kopf et al. 2007 counter with histogram matching, and Chen and Wang 2010 with
//! position-histogram matching: penalize the exemplar positions used more often than the others.
//!
//! How, keeping the solid lazy and spatially deterministic. Those methods re-weight with the
//! histogram of the volume being synthesized, a global quantity a lazy synthesis never has. Here
//! the histogram is measured once, at analysis time, on calibration solids: `rounds` tileable
//! solids of `calibration_size` voxels per side (seeds from [`CALIBRATION_SEED`]), each synthesized with
//! the penalties found so far. After each, every level's usage of every exemplar pixel (all
//! three coordinates of every voxel, per exemplar; one histogram when one image serves all
//! axes) is divided by its mean and added up over the rounds; a pixel's penalty is then
//! `strength * max(0, average ratio - 1)`, in sixteenths, at most [`MAX_PENALTY`]. The penalties
//! are part of the analysis (stored in the .ssa), so every solid synthesized from it, of any
//! size and anywhere, uses the same ones.
//!
//! The correction scales every candidate's distance by (16 + the penalties of its pixels) / 16
//! (one pixel for a 2D candidate, three for a triple), in integers on both backends. With no
//! balancing all penalties are zero, every distance is scaled by the same 16, and the choices are
//! exactly the paper's.

use crate::analysis::balance::MAX_PENALTY;
use crate::analysis::{Analysis, AnalysisInput, AnalysisParams};
use crate::backend::Compute;
use crate::error::Result;
use crate::lazy::{SynthParams, Synthesizer};

/// Analyse the exemplars ([`crate::analysis::analyze_unbalanced`]) and measure their usage
/// penalties ([`balance`]): the analysis every synthesis reads. `progress` gets (stage, fraction
/// of the whole), the balancing the last tenth.
pub fn analyze(
    input: &AnalysisInput,
    params: &AnalysisParams,
    compute: &Compute,
    progress: &(dyn Fn(&str, f32) + Sync),
) -> Result<Analysis> {
    let mut analysis = crate::analysis::analyze_unbalanced(input, params, compute, &|stage, f| {
        progress(stage, 0.9 * f)
    })?;
    balance(&mut analysis, compute, &|stage, f| {
        progress(&format!("usage balancing: {stage}"), 0.9 + 0.1 * f)
    })?;
    progress("done", 1.0);
    Ok(analysis)
}

/// Seed of the first calibration solid, the next rounds' are the following ones (any fixed
/// values: the analysis must not depend on the user's synthesis seed).
pub const CALIBRATION_SEED: u64 = 0x0BA1_A4CE;

/// Edge of the calibration solids for an exemplar of `pixels` pixels: large enough that the
/// coarsest synthesized level (an eighth of the edge, against an eighth of the exemplar's) holds
/// about four coordinates per exemplar pixel, 3 (N/8)^3 >= 4 pixels / 64, i.e.
/// N >= 2 (4/3 pixels)^(1/3); a multiple of 32 (tileable solids in one piece need it), at most
/// 128 (two coordinates per pixel at 512^2: each 160^3 round costs ~11 s on 2 cores, a 128^3 one ~5 s).
/// (Measured: half that, 32 instead of 64 for 64^2 to 115^2 exemplars, left the balanced solids'
/// usage twice as concentrated on a 64^2 brick and raised histogram ratios by a quarter to a
/// third on 96^2 and 115^2 photographs.)
pub fn calibration_size(pixels: u64) -> u32 {
    let side = (2.0 * ((4.0 / 3.0) * pixels as f64).cbrt()).ceil() as u32;
    side.next_multiple_of(32).clamp(32, 128)
}

/// Measure and set the penalties of `analysis` (its params say how many rounds and how strong).
/// `progress` gets (stage, fraction of the balancing).
pub fn balance(
    analysis: &mut Analysis,
    compute: &Compute,
    progress: &(dyn Fn(&str, f32) + Sync),
) -> Result<()> {
    let rounds = analysis.params.balance_rounds;
    for ex in &mut analysis.exemplars {
        for level in &mut ex.levels {
            level.penalty.iter_mut().for_each(|p| *p = 0);
        }
    }
    if rounds == 0 {
        return Ok(());
    }
    let strength = analysis.params.balance_strength as f64;
    let levels = analysis.level_count();
    let finest = &analysis.exemplars[0].levels[0].image;
    let size = calibration_size(finest.pixel_count() as u64);
    // Accumulated usage ratios: [owner][level][pixel].
    let started = std::time::Instant::now();
    let mut ratios: Vec<Vec<Vec<f64>>> = analysis
        .exemplars
        .iter()
        .map(|ex| {
            ex.levels
                .iter()
                .map(|l| vec![0.0; l.image.pixel_count()])
                .collect()
        })
        .collect();
    for round in 0..rounds {
        progress(
            &format!("round {} of {rounds} ({size}^3)", round + 1),
            round as f32 / rounds as f32,
        );
        // A new solid each round: with the same one every round the penalties swing with that
        // one solid (the built-in exemplar's grey cells were nearly half of one analysis' solids
        // and absent from the next's).
        let params = SynthParams {
            seed: CALIBRATION_SEED + round as u64,
            ..Default::default()
        };
        let mut synth = Synthesizer::new(analysis, params, compute)?;
        synth.count_usage();
        synth.synthesize_tileable(size, &|_, _| {}, false)?;
        let usage = synth.take_usage().expect("counting was enabled");
        for (pack, per_exemplar) in usage.iter().enumerate() {
            // Packs run coarsest first; analysis levels finest first.
            let level = levels - 1 - pack;
            for (owner, owner_ratios) in ratios.iter_mut().enumerate() {
                let counts: Vec<u64> = if analysis.shared {
                    (0..per_exemplar[0].len())
                        .map(|i| per_exemplar.iter().map(|c| c[i]).sum())
                        .collect()
                } else {
                    per_exemplar[owner].clone()
                };
                let total: u64 = counts.iter().sum();
                let mean = total as f64 / counts.len() as f64;
                for (r, &c) in owner_ratios[level].iter_mut().zip(&counts) {
                    *r += c as f64 / mean;
                }
            }
        }
        let done = (round + 1) as f64;
        for (ex, owner_ratios) in analysis.exemplars.iter_mut().zip(&ratios) {
            for (l, level_ratios) in ex.levels.iter_mut().zip(owner_ratios) {
                for (p, &r) in l.penalty.iter_mut().zip(level_ratios) {
                    let over = (r / done - 1.0).max(0.0);
                    *p = (16.0 * strength * over).round().min(MAX_PENALTY as f64) as u8;
                }
            }
        }
    }
    tracing::info!(
        "usage balancing: {rounds} calibration solids of {size}^3 in {:.2} s",
        started.elapsed().as_secs_f64()
    );
    progress("done", 1.0);
    Ok(())
}

/// Share of all coordinates held by the most-used 1% of the pixels (at least one pixel):
/// the concentration balancing reduces (1% when usage is uniform).
#[cfg(any(test, feature = "internals"))]
pub fn top_percent_share(counts: &[u64]) -> f64 {
    let mut sorted = counts.to_vec();
    sorted.sort_unstable_by(|a, b| b.cmp(a));
    let total: u64 = sorted.iter().sum();
    let top: u64 = sorted[..(sorted.len() / 100).max(1)].iter().sum();
    top as f64 / total.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calibration_size_grows_with_the_exemplar() {
        assert_eq!(calibration_size(32 * 32), 32);
        assert_eq!(calibration_size(64 * 64), 64);
        assert_eq!(calibration_size(96 * 96), 64);
        assert_eq!(calibration_size(128 * 128), 64);
        assert_eq!(calibration_size(256 * 256), 96);
        assert_eq!(calibration_size(512 * 512), 128);
        assert_eq!(calibration_size(2048 * 2048), 128);
        assert_eq!(calibration_size(8192 * 8192), 128);
    }

    #[test]
    fn top_share_of_uniform_and_concentrated_usage() {
        let uniform = vec![5u64; 1000];
        assert!((top_percent_share(&uniform) - 0.01).abs() < 1e-12);
        let mut peaked = vec![1u64; 1000];
        peaked[3] = 1000;
        assert!(top_percent_share(&peaked) > 0.5);
    }
}
