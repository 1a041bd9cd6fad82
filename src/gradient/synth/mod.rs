//! Direct synthesis of a gradient solid from a 2D exemplar (paper section 4): texture
//! optimization over the control points instead of voxels.
//!
//! Per level (three, coarse to fine, with N = 9, 11, 21 samples per slice side at sample
//! spacings 4, 2, 1 voxels: the control grid stays fixed, 4.2.3) and per iteration (N_O = 3):
//! 1. every cube of the control grid gets N_C = 3 seeded random check points; at each, three
//!    orthogonal N x N slices of the current solid are evaluated with the first-order Taylor
//!    approximation (4.2.4) and matched to exemplar patches through a PCA projection and an
//!    approximate nearest-neighbour index ([`ivf`]), E_y and E_z among the patches most
//!    crossbar-consistent with E_x (and E_y), sets precomputed per level (4.2.1, [`matching`],
//!    [`crossbar`]);
//! 2. the matched patches' samples go into per-voxel buckets, at the finest level with colour
//!    quantization (two passes: per-cluster counts, then sums of the two dominant clusters);
//!    buckets live only for one control layer at a time (bucket reuse, O(n^2 N) memory), and
//!    each control point is refitted to the buckets nearest to it by eq. 2 ([`buckets`]).
//!
//! Every iteration reads the previous iteration's solid and writes a new one (Jacobi order), so
//! the result does not depend on the order of the work: same exemplar, parameters and seed give
//! the same bytes at any thread count and on either backend (the bucket kernel uses integer
//! atomics; everything else runs on the CPU).
//!
//! The solid is periodic with period P = 4 m voxels (m control cells per axis): slices that
//! leave the domain wrap around, so there is no boundary to treat specially, and the output
//! tiles space seamlessly. It is written with m + 1 points per axis (the last face repeats the
//! first), covering [0, P]^3.
//!
//! Optionally (`optimize_iterations`), the final control-point optimization of eq. 3 fits all
//! points at once to the last iteration's bucket values ([`refine`]).
//!
//! With a binary mask ([`synthesize_regions`]; paper 3.2, 4.2.2, 4.3) the exemplar gets the
//! mask's signed distance as a fourth channel ([`MaskedExemplar`]), synthesized like a colour
//! (4.2.4: intermediate synthesis ignores the regions; histogram matching then also keeps the
//! region fractions), the colour clusters are allocated per region
//! ([`clusters::quantize_regions`]), the last iteration's buckets average one region's samples
//! per voxel, and [`separate`] turns those dense samples into a tileable
//! [`RegionSolid`] (distance field + f^P / f^N at the split points). Sizes up to
//! [`MAX_OPTIMIZE_SIZE`] (the dense samples). Deviations from the paper: the distance solid is
//! the transform of the synthesized distance's sign (thresholded samples), not the synthesized
//! distance values themselves; the boundary samples are not dilated into the neighbouring
//! cubes (the split points' fits use the voxels of their sign within their 9^3 neighbourhood,
//! as the vectorizer does); the final fit is eq. 2 on voxels (and eq. 3 with `--optimize`)
//! rather than on the raw samples.

pub mod buckets;
pub mod clusters;
pub mod crossbar;
pub mod folded;
pub mod frame;
pub mod ivf;
pub mod matching;
mod params;
pub mod patches;
pub mod pca;
mod periodic;
pub mod refine;
pub mod separate;

use super::regions::RegionSolid;
use super::SPACING;
use crate::backend::Compute;
use crate::error::{Error, Result};
use crate::exemplar::Image;
use crate::util::hash::mix64;
pub use frame::Field;
pub use params::*;
use patches::LevelPatches;
pub use periodic::{wrap, PeriodicSolid};
use std::time::Instant;

/// What a synthesis did, per level.
#[derive(Clone, Debug, Default)]
pub struct SynthReport {
    pub levels: Vec<LevelReport>,
    pub seconds: f64,
    /// Time of the final optimization and the RMS error to its samples before and after.
    pub optimize_seconds: f64,
    pub optimize_rms: (f64, f64),
    /// With a mask: the final region separation.
    pub regions: Option<RegionReport>,
}

/// The final region separation of a synthesis with a mask.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RegionReport {
    /// Control points carrying two feature sets, of all points.
    pub split_points: usize,
    pub points: usize,
    /// Fraction of one period's voxels on the positive side of the stored distance, and of the
    /// exemplar's pixels set in the mask.
    pub positive_fraction: f64,
    pub exemplar_positive_fraction: f64,
    /// Fraction of voxels whose last buckets were empty (filled from the solid).
    pub empty_buckets: f64,
    pub seconds: f64,
}

#[derive(Clone, Debug)]
pub struct LevelReport {
    pub spec: LevelSpec,
    pub candidates: usize,
    pub pca_energy: f64,
    pub prepare_seconds: f64,
    pub match_seconds: f64,
    pub update_seconds: f64,
    /// Fraction of control points refitted in the last iteration (the others had no samples).
    pub refitted: f64,
}

/// Progress: (message, fraction of the whole job).
pub type Progress<'a> = &'a (dyn Fn(&str, f32) + Sync);

/// The exemplar as RGB (gradient solids store colour; alpha and gray are expanded/dropped).
fn colour_exemplar(img: &Image) -> Image {
    img.with_channels(3)
}

/// An exemplar with a binary mask (paper 3.2, 4): RGB plus the mask's signed distance as a
/// fourth channel.
///
/// The distance is the crate's feature channel ([`crate::exemplar::feature::feature_channel`],
/// as in \[29\] / Lefebvre-Hoppe): 128 + k d with k = 127 / 12 (10.6 levels per pixel, saturating
/// 12 pixels from the boundary), positive where the mask is set; the boundary pixels encode to
/// 133 (set) and 123 (clear), so the sign survives 8 bits. With that k the channel spans the
/// same 0..255 range as a colour channel over the 24 pixels around a boundary, and in a patch
/// distance it weighs like one strongly contrasted colour channel: enough to make patches
/// respect the boundaries, not so much that it swamps the three colours (a larger k saturates
/// sooner and only adds a plateau; a smaller one lets colour alone decide).
#[derive(Clone, Debug)]
pub struct MaskedExemplar {
    pub image: Image,
    /// Fraction of the exemplar's pixels set in the mask.
    pub positive_fraction: f64,
}

impl MaskedExemplar {
    /// `mask`: same size as `exemplar`, set where its first channel is >= 128, with both
    /// regions present. `mask_name` labels errors (e.g. "--mask m.png").
    pub fn new(exemplar: &Image, mask: &Image, mask_name: &str) -> Result<MaskedExemplar> {
        exemplar.check("exemplar")?;
        let colour = colour_exemplar(exemplar);
        let distance = crate::exemplar::feature::feature_channel(
            mask,
            &colour,
            mask_name,
            crate::exemplar::Border::Mirror,
        )?;
        let set = distance.pixels.iter().filter(|&&v| v >= 128).count();
        Ok(MaskedExemplar {
            image: colour.with_extra_channels(&distance),
            positive_fraction: set as f64 / distance.pixels.len() as f64,
        })
    }
}

impl GradientSynthParams {
    /// The extra limits of a synthesis with a mask: its region separation keeps every voxel's
    /// last sample (as `--optimize` does), so sizes up to [`MAX_OPTIMIZE_SIZE`].
    pub fn validate_with_mask(&self) -> Result<()> {
        self.validate()?;
        if self.size > MAX_OPTIMIZE_SIZE {
            return Err(Error::invalid(
                format!("--mask with --size {}", self.size),
                format!(
                    "region separation keeps every voxel's last sample: at most \
                     {MAX_OPTIMIZE_SIZE}^3"
                ),
            ));
        }
        // Eq. 3 over both region sets of the padded volume: 875 MB peak at 128 (measured),
        // about 8x that at 256.
        if self.optimize_iterations > 0 && self.size > MAX_MASK_OPTIMIZE_SIZE {
            return Err(Error::invalid(
                format!("--mask --optimize with --size {}", self.size),
                format!(
                    "the region refinement needs about 7 GB at 256^3: at most \
                     {MAX_MASK_OPTIMIZE_SIZE}^3 (or drop --optimize)"
                ),
            ));
        }
        Ok(())
    }

    /// The bytes a synthesis from `exemplar` (with `masked`, its distance channel included)
    /// holds at most, about, from peaks measured on the 2-core Xeon development machine: the
    /// exemplar's patch index (40 MB at 128^2 pixels, 190 MB at 2048^2), four copies of the
    /// control points (the current and next iterations, the solid and its file: 88 MB at
    /// `--size 256`), and the dense samples the region separation (44 bytes a voxel at 128^3)
    /// and eq. 3 (114, and about 400 with both at 128^3) keep. Rounded up from those.
    pub fn memory_bytes(&self, exemplar: &Image, masked: bool) -> u64 {
        let channels = exemplar.channels as u64;
        let index = (64 << 20) + 48 * exemplar.pixel_count() as u64;
        let points = (self.cells() as u64).pow(3);
        let solid = 4 * points * channels * 4 * 4;
        let voxels = (self.cells() as u64 * SPACING as u64).pow(3);
        let samples = match (masked, self.optimize_iterations > 0) {
            (false, false) => 0,
            (true, false) => 48,
            (false, true) => 40 * channels,
            (true, true) => 420,
        } * voxels;
        index + solid + samples
    }

    /// Refuse a synthesis whose [`memory_bytes`](Self::memory_bytes) exceed the memory
    /// available, before it starts.
    pub fn check_memory(&self, exemplar: &Image, masked: bool) -> Result<()> {
        use crate::util::memory::{available_memory, available_text, human_bytes};
        let (estimate, available) = (self.memory_bytes(exemplar, masked), available_memory());
        if estimate > available {
            return Err(Error::invalid(
                format!("--size {}", self.size),
                format!(
                    "needs about {} of memory, {}",
                    human_bytes(estimate),
                    available_text(available)
                ),
            ));
        }
        Ok(())
    }
}

/// Synthesize a periodic gradient solid from `exemplar` (paper section 4).
pub fn synthesize(
    exemplar: &Image,
    params: &GradientSynthParams,
    compute: &Compute,
    progress: Progress,
) -> Result<(PeriodicSolid, SynthReport)> {
    params.validate()?;
    crate::exemplar::check_exemplar_size(exemplar, "exemplar")?;
    params.check_memory(exemplar, false)?;
    let (solid, report, _) = iterate(&colour_exemplar(exemplar), false, params, compute, progress)?;
    Ok((solid, report))
}

/// Synthesize with region separation (paper 3.2, 4.2.2, 4.3): the iterations run on colour +
/// signed distance with mask-aware colour clusters; then the last samples are separated into a
/// [`RegionSolid`] of period P (its last faces equal its first; see [`separate`]). With
/// `optimize_iterations`, eq. 3 refines both feature sets ([`RegionSolid::optimize`]).
pub fn synthesize_regions(
    exemplar: &MaskedExemplar,
    params: &GradientSynthParams,
    compute: &Compute,
    progress: Progress,
) -> Result<(RegionSolid, SynthReport)> {
    params.validate_with_mask()?;
    params.check_memory(&exemplar.image, true)?;
    let start = Instant::now();
    let (solid, mut report, targets) = iterate(&exemplar.image, true, params, compute, progress)?;
    let targets = targets.expect("a synthesis with a mask keeps its last samples");
    progress("region separation", 0.99);
    let t = Instant::now();
    let (rs, sep) = separate::separate(&solid, &targets, params.optimize_iterations as usize)?;
    if let Some(rms) = sep.optimize_rms {
        report.optimize_rms = rms;
        report.optimize_seconds = t.elapsed().as_secs_f64();
    }
    report.regions = Some(RegionReport {
        split_points: rs.split_points(),
        points: rs.split.len(),
        positive_fraction: separate::positive_fraction(&rs),
        exemplar_positive_fraction: exemplar.positive_fraction,
        empty_buckets: sep.empty,
        seconds: t.elapsed().as_secs_f64(),
    });
    progress("done", 1.0);
    report.seconds = start.elapsed().as_secs_f64();
    Ok((rs, report))
}

/// The levels and iterations of section 4 on `exemplar` (colour channels, then with
/// `masked` the signed distance as the last channel). Returns the solid, the report and, when
/// asked for (`masked` or eq. 3), the last iteration's samples.
fn iterate(
    exemplar: &Image,
    masked: bool,
    params: &GradientSynthParams,
    compute: &Compute,
    progress: Progress,
) -> Result<(PeriodicSolid, SynthReport, Option<refine::Targets>)> {
    let start = Instant::now();
    let distance_channel = masked.then(|| exemplar.channels as usize - 1);
    let mut kept = None;
    let mut solid = PeriodicSolid::random(params.cells(), exemplar, params.seed);
    let mut report = SynthReport::default();
    let steps = (params.levels.len() * params.iterations as usize) as f32;
    let finest = params.levels.len() - 1;
    for (li, spec) in params.levels.iter().enumerate() {
        let t0 = Instant::now();
        progress(
            &format!("level {li}: exemplar patches"),
            (li * params.iterations as usize) as f32 / steps,
        );
        let patches = LevelPatches::build(
            exemplar,
            spec.spacing,
            spec.size,
            (params.quantize_all_levels || li == finest).then_some(params.clusters),
            distance_channel,
            mix64(params.seed ^ li as u64),
        )?;
        let t_sets = Instant::now();
        let sets = match params.search {
            SliceSearch::Crossbar { n1, n2 } => Some(crossbar::CrossbarSets::build(
                &patches,
                params.matched_slices == 3,
                n1.max(n2) as usize,
                mix64(params.seed ^ 0xc805_0000 ^ li as u64),
            )),
            _ => None,
        };
        tracing::debug!(
            "level {li}: patches {:.3} s, crossbar sets {:.3} s",
            (t_sets - t0).as_secs_f64(),
            t_sets.elapsed().as_secs_f64()
        );
        let mut level = LevelReport {
            spec: *spec,
            candidates: patches.candidates(),
            pca_energy: patches.pca().energy_kept,
            prepare_seconds: t0.elapsed().as_secs_f64(),
            match_seconds: 0.0,
            update_seconds: 0.0,
            refitted: 0.0,
        };
        for it in 0..params.iterations {
            progress(
                &format!("level {li} iteration {it}"),
                (li * params.iterations as usize + it as usize) as f32 / steps,
            );
            let t1 = Instant::now();
            let ctx = matching::MatchContext {
                params,
                level: li as u32,
                iteration: it,
                patches: &patches,
                sets: sets.as_ref(),
            };
            let points = matching::check_points(solid.m, &ctx);
            let matches = matching::match_all(&solid, &ctx, &points);
            let t2 = Instant::now();
            let last = li == finest && it + 1 == params.iterations;
            let mut targets = (last && (masked || params.optimize_iterations > 0))
                .then(|| refine::Targets::empty(solid.period() as usize, solid.channels));
            let (next, refitted) =
                buckets::update(&solid, &points, &matches, &ctx, compute, targets.as_mut())?;
            solid = next;
            if params.histogram_matching {
                solid.match_histogram(&patches.filtered_values());
            }
            if tracing::enabled!(tracing::Level::DEBUG) {
                let distinct: std::collections::BTreeSet<u32> =
                    matches.iter().flatten().copied().collect();
                tracing::debug!(
                    "level {li} iteration {it}: {} distinct patches matched, value spread {:.1}",
                    distinct.len(),
                    solid.value_spread()
                );
            }
            level.match_seconds += (t2 - t1).as_secs_f64();
            level.update_seconds += t2.elapsed().as_secs_f64();
            level.refitted = refitted;
            if masked {
                // The region separation fits (and optimizes) its own solid from the samples.
                kept = targets;
            } else if let Some(targets) = &targets {
                progress("final optimization (eq. 3)", 0.99);
                let t3 = Instant::now();
                let history =
                    refine::optimize(&mut solid, targets, params.optimize_iterations as usize);
                report.optimize_seconds = t3.elapsed().as_secs_f64();
                report.optimize_rms = (history[0], *history.last().unwrap());
            }
        }
        report.levels.push(level);
    }
    if !masked {
        progress("done", 1.0);
    }
    report.seconds = start.elapsed().as_secs_f64();
    Ok((solid, report, kept))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taylor_evaluation_is_exact_on_linear_fields_across_the_wrap() {
        // f = 10 + 2x at every point with gradient (2, 0, 0): exact near each point; the wrap
        // only changes which point is nearest.
        let m = 4;
        let mut s = PeriodicSolid {
            m,
            channels: 1,
            data: vec![0.0; 64 * 4],
        };
        for z in 0..4 {
            for y in 0..4 {
                for x in 0..4i64 {
                    let o = s.offset([x, y, z]);
                    s.data[o] = 10.0 + 8.0 * x as f32;
                    s.data[o + 1] = 2.0;
                }
            }
        }
        let mut out = [0f32];
        s.taylor([5, 0, 0], &mut out);
        assert_eq!(out[0], 20.0); // point 1 (x = 4), offset +1
        s.taylor([-1, 3, 7], &mut out);
        assert_eq!(out[0], 8.0); // point 0, offset -1
        s.taylor([14, 0, 0], &mut out); // nearest point 4 = point 0 wrapped, offset -2
        assert_eq!(out[0], 6.0);
        assert_eq!(PeriodicSolid::nearest_point([6, -2, 2]).1, [-2, -2, -2]);
    }
}
