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
use patches::LevelPatches;
pub use periodic::{wrap, PeriodicSolid};
use std::time::Instant;

/// One synthesis level: slices of `size` samples per side, `spacing` voxels (and exemplar
/// pixels) apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelSpec {
    pub spacing: u32,
    pub size: u32,
}

/// The paper's three levels, coarse to fine (4.2.3).
pub const PAPER_LEVELS: [LevelSpec; 3] = [
    LevelSpec {
        spacing: 4,
        size: 9,
    },
    LevelSpec {
        spacing: 2,
        size: 11,
    },
    LevelSpec {
        spacing: 1,
        size: 21,
    },
];

/// How the three slices of a check point are matched (4.2.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SliceSearch {
    /// Three independent nearest-patch searches (as in Kopf et al.).
    Independent,
    /// The paper's: E_x nearest to s_x; E_y the nearest to s_y among the `n1` candidates most
    /// crossbar-consistent with E_x; E_z the nearest to s_z among the `n2` most consistent with
    /// both ([`crossbar`]: the sets are precomputed per level).
    Crossbar { n1: u32, n2: u32 },
    /// The other way round (another reading of the paper's sentence, kept for comparison): E_y
    /// the most crossbar-consistent with E_x among the `n1` nearest to s_y; E_z the most
    /// consistent with both among the `n2` nearest to s_z. Two k-nearest searches per check
    /// point.
    CrossbarNearest { n1: u32, n2: u32 },
}

#[derive(Clone, Debug)]
pub struct GradientSynthParams {
    pub seed: u64,
    /// Requested edge in voxels; the period is this rounded up to a multiple of 4.
    pub size: u32,
    /// N_O: iterations per level.
    pub iterations: u32,
    /// N_C: check points per cube.
    pub check_points: u32,
    /// N_T: colour clusters of the finest level's buckets.
    pub clusters: u32,
    pub search: SliceSearch,
    /// Slices matched per check point: 3, or 2 (those orthogonal to x and y; the z slice is
    /// left free) for anisotropic exemplars that cannot hold on all three planes (4.2.1).
    pub matched_slices: u32,
    /// Quantize the buckets of every level, not only the finest (the paper's choice). Without
    /// it, the first iterations from a random start average unrelated patches and the solid
    /// collapses towards the mean colour (measured: value spread 60 -> 2.4 in two iterations).
    pub quantize_all_levels: bool,
    /// After each update, map the control values of each channel onto the exemplar's histogram
    /// (Kopf et al. 2007's remedy; not in the paper): keeps the contrast the averaging of
    /// patches loses.
    pub histogram_matching: bool,
    pub levels: Vec<LevelSpec>,
    pub field: Field,
    /// CGNR steps of the final eq. 3 optimization (0: off, the paper's default).
    pub optimize_iterations: u32,
    /// Nearest-patch search: `None` exact (exhaustive); `Some(p)` approximate, scanning the `p`
    /// lists of the candidates' inverted-file partition nearest to each query (of about
    /// sqrt(candidates) lists; see [`patches::LevelPatches::nearest`]).
    pub probes: Option<u32>,
}

impl Default for GradientSynthParams {
    fn default() -> Self {
        GradientSynthParams {
            seed: 0,
            size: 64,
            iterations: 3,
            check_points: 3,
            clusters: 12,
            search: SliceSearch::Crossbar { n1: 20, n2: 50 },
            matched_slices: 3,
            quantize_all_levels: true,
            histogram_matching: true,
            levels: PAPER_LEVELS.to_vec(),
            field: Field::None,
            optimize_iterations: 0,
            probes: Some(DEFAULT_PROBES),
        }
    }
}

/// Lists probed by the default approximate nearest-patch search (of ~128 at the finest level).
/// Measured at 96^3 on nine exemplars (BENCHMARKS.md): 4 probes give eval ratios within the
/// seed-to-seed spread of 8 probes' and of the exact search's, in 15-20% less time than 8.
pub const DEFAULT_PROBES: u32 = 4;

/// Most lists an approximate search may probe (`--probes`; 0 there is the exact search).
pub const MAX_PROBES: u32 = 65536;

/// Most synthesis levels ([`GradientSynthParams::levels`]).
pub const MAX_LEVELS: usize = 8;
/// Largest slice a level matches, in samples per side (the paper's finest is 21).
pub const MAX_LEVEL_SLICE: u32 = 63;
/// Largest spacing of a level's samples (the paper's coarsest is 4).
pub const MAX_LEVEL_SPACING: u32 = 64;

/// Largest accepted size (the control grid of 1024^3 is 256^3 points).
pub const MAX_SIZE: u32 = 1024;
/// Largest size of `--mask --optimize` (measured: 875 MB peak RSS at 128).
pub const MAX_MASK_OPTIMIZE_SIZE: u32 = 128;
/// Largest size of the final optimization (its samples take 12 bytes per voxel: 200 MB).
pub const MAX_OPTIMIZE_SIZE: u32 = 256;

impl GradientSynthParams {
    pub fn validate(&self) -> Result<()> {
        if !(16..=MAX_SIZE).contains(&self.size) {
            return Err(Error::invalid(
                format!("--size {}", self.size),
                format!("must be 16..={MAX_SIZE} voxels"),
            ));
        }
        let bounded = |name: &str, v: u32, max: u32| {
            if (1..=max).contains(&v) {
                Ok(())
            } else {
                Err(Error::invalid(
                    format!("{name} {v}"),
                    format!("must be 1..={max}"),
                ))
            }
        };
        bounded("--iterations", self.iterations, 20)?;
        bounded("--check-points", self.check_points, 16)?;
        bounded("--clusters", self.clusters, 32)?;
        if !(2..=3).contains(&self.matched_slices) {
            return Err(Error::invalid(
                format!("--slices {}", self.matched_slices),
                "must be 2 or 3",
            ));
        }
        if self.optimize_iterations > 0 && self.size > MAX_OPTIMIZE_SIZE {
            return Err(Error::invalid(
                format!("--optimize with --size {}", self.size),
                format!(
                    "the final optimization keeps every voxel's sample: at most \
                     {MAX_OPTIMIZE_SIZE}^3"
                ),
            ));
        }
        if let Some(probes) = self.probes.filter(|p| !(1..=MAX_PROBES).contains(p)) {
            return Err(Error::invalid(
                format!("--probes {probes}"),
                format!("must be 0 (the exact search) or 1..={MAX_PROBES}"),
            ));
        }
        if let SliceSearch::Crossbar { n1, n2 } | SliceSearch::CrossbarNearest { n1, n2 } =
            self.search
        {
            bounded("crossbar candidates N1", n1, 256)?;
            bounded("crossbar candidates N2", n2, 256)?;
        }
        if !(1..=MAX_LEVELS).contains(&self.levels.len())
            || self.levels.iter().any(|l| {
                l.size % 2 == 0
                    || !(3..=MAX_LEVEL_SLICE).contains(&l.size)
                    || !(1..=MAX_LEVEL_SPACING).contains(&l.spacing)
            })
        {
            return Err(Error::invalid(
                format!("levels {:?}", self.levels),
                format!(
                    "need 1 to {MAX_LEVELS} levels, each with an odd slice size in \
                     3..={MAX_LEVEL_SLICE} and a spacing in 1..={MAX_LEVEL_SPACING}"
                ),
            ));
        }
        Ok(())
    }

    /// The slice axes: cyclic (the crate's frame) with three matched slices, upright with two.
    pub fn slice_axes(&self) -> frame::SliceAxes {
        if self.matched_slices == 3 {
            frame::SliceAxes::Cyclic
        } else {
            frame::SliceAxes::Upright
        }
    }

    /// Smallest exemplar side the levels' patches fit in.
    pub fn min_exemplar_side(&self) -> u32 {
        self.levels
            .iter()
            .map(|l| (l.size - 1) * l.spacing + 1)
            .max()
            .unwrap_or(1)
    }

    /// Control cells per axis: the period in units of the spacing.
    pub fn cells(&self) -> u32 {
        self.size.div_ceil(SPACING)
    }
}

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
