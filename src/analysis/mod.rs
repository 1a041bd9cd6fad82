//! Exemplar analysis (paper section 4): pyramids, PCA bases, projected neighbourhoods, k-coherent
//! 2D candidates, crossbar-consistent and coherence-filtered 3D candidates, and candidate slabs.
//! Everything synthesis needs, persisted by `io::ssa`.

pub mod balance;
pub mod coherence;
pub mod crossbar;
pub mod frame;
pub mod kcoherent;
pub mod neighbourhood;
pub mod pca;
pub mod slab;

use crate::backend::Compute;
use crate::error::{Error, Result};
use crate::exemplar::{self, feature, pyramid, Border, Image};
use coherence::Grid;
use frame::{next, rotate_from_shared, NEIGHBOURHOOD_PIXELS, NO_COORD};

/// Bumped whenever the analysis computes something different from the same inputs and
/// parameters (e.g. the balancing's calibration sizes; 2: PCA weights limited to 16 bits; 3: the
/// calibration solids synthesized with brick-local sub-passes; 4: a new calibration seed each
/// round), so cached analyses are recomputed.
pub const ALGORITHM_REVISION: u32 = 4;

/// Pyramid levels analysed: synthesis starts three levels above the finest (l_start = L - 3).
pub const ANALYSED_LEVELS: usize = 4;

/// Tunables of the analysis. Arrays indexed by level, finest first.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalysisParams {
    /// PCA dimensions kept per level (8 or 12; more at coarse levels, where the first
    /// components capture less of the variance).
    pub pca_dims: [u32; ANALYSED_LEVELS],
    /// k-coherent 2D candidates per pixel (the pixel itself included).
    pub k2d: [u32; ANALYSED_LEVELS],
    /// S: strips fetched per axis for the crossbar search.
    pub strips_per_axis: u32,
    /// Triples kept per pixel after the crossbar ranking.
    pub crossbar_keep: u32,
    /// 3D candidates kept per pixel after the coherence filter.
    pub max_3d: u32,
    /// Cap on coherence-filter rounds (the paper: "typically 2 iterations"). 4 keeps the
    /// synthesis quality of 32 (measured) at 60% of the analysis time at 128^2.
    pub max_filter_rounds: u32,
    /// Weight of the feature-distance channel relative to a colour channel.
    pub feature_weight: f32,
    /// Usage-balancing rounds ([`balance`]): calibration syntheses that find the exemplar
    /// pixels the correction over-uses. 0 keeps the paper's unmodified search.
    pub balance_rounds: u32,
    /// How strongly an over-used pixel is penalized ([`balance`]).
    pub balance_strength: f32,
}

/// Default weight of the feature channel against one colour channel. 3 (with the automatic
/// masks of [`crate::exemplar::feature::auto_masks`]) was measured on eleven exemplars
/// (BENCHMARKS.md, Quality): it sharpens thin structure most without moving the colour
/// histogram much; 1 barely changes the search.
pub const DEFAULT_FEATURE_WEIGHT: f32 = 3.0;

impl Default for AnalysisParams {
    fn default() -> Self {
        AnalysisParams {
            pca_dims: [8, 12, 12, 12],
            k2d: [2, 4, 4, 4],
            strips_per_axis: 65,
            crossbar_keep: 100,
            max_3d: 12,
            max_filter_rounds: 4,
            feature_weight: DEFAULT_FEATURE_WEIGHT,
            balance_rounds: balance::DEFAULT_ROUNDS,
            balance_strength: 1.0,
        }
    }
}

impl AnalysisParams {
    pub fn validate(&self) -> Result<()> {
        if self.pca_dims.iter().any(|&d| d != 8 && d != 12) {
            return Err(Error::invalid("PCA dimensions", "each level keeps 8 or 12"));
        }
        if self.k2d.iter().any(|&k| !(1..=8).contains(&k)) {
            return Err(Error::invalid("2D candidates", "1..=8 per pixel"));
        }
        if !(1..=256).contains(&self.strips_per_axis) {
            return Err(Error::invalid(
                format!("--strips {}", self.strips_per_axis),
                "must be 1..=256",
            ));
        }
        if !(1..=1000).contains(&self.crossbar_keep) {
            return Err(Error::invalid(
                format!("--crossbar-keep {}", self.crossbar_keep),
                "must be 1..=1000",
            ));
        }
        if !(1..=32).contains(&self.max_3d) {
            return Err(Error::invalid(
                format!("--max-candidates {}", self.max_3d),
                "must be 1..=32",
            ));
        }
        if !(self.feature_weight.is_finite() && (0.0..=16.0).contains(&self.feature_weight)) {
            return Err(Error::invalid(
                format!(
                    "--feature-weight {}",
                    crate::util::number_text(self.feature_weight as f64)
                ),
                "must be a number in 0..=16",
            ));
        }
        if self.balance_rounds > balance::MAX_ROUNDS {
            return Err(Error::invalid(
                format!("--balance-rounds {}", self.balance_rounds),
                format!("must be 0..={}", balance::MAX_ROUNDS),
            ));
        }
        if !(self.balance_strength.is_finite() && (0.0..=8.0).contains(&self.balance_strength)) {
            return Err(Error::invalid(
                format!(
                    "--balance-strength {}",
                    crate::util::number_text(self.balance_strength as f64)
                ),
                "must be a number in 0..=8",
            ));
        }
        Ok(())
    }
}

/// What the analysis starts from.
#[derive(Clone, Debug)]
pub struct AnalysisInput {
    /// One image (used for all three axes) or three (Ex, Ey, Ez).
    pub exemplars: Vec<Image>,
    /// Optional feature masks, one per exemplar given (all or none).
    pub masks: Vec<Image>,
    /// Whether the exemplars tile.
    pub border: Border,
    /// Names for error messages, parallel to `exemplars` (e.g. "exemplar a.png", "--ey b.png").
    pub names: Vec<String>,
}

/// Per-level statistics kept with the analysis.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LevelStats {
    /// Mean over pixels of the lowest crossbar error before filtering.
    pub mean_best_cb: f64,
    /// Coherence-filter rounds run.
    pub filter_rounds: u32,
}

/// Everything about one exemplar at one pyramid level.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelData {
    /// Colour channels, then the feature channel if any.
    pub image: Image,
    pub pca: pca::PcaBasis,
    /// Quantized projections, `pca.words_per_vector()` u32 words per pixel.
    pub projected: Vec<u32>,
    /// `k2d` packed coordinates per pixel.
    pub candidates_2d: Vec<u32>,
    /// `max_3d` triples per pixel (packed coordinates in Ex, Ey, Ez), unused slots NO_COORD.
    /// Empty for Ey and Ez of a shared analysis (their sets are rotations of Ex's).
    pub candidates_3d: Vec<[u32; 3]>,
    pub counts_3d: Vec<u8>,
    /// The slab triple of each pixel: its first 3D candidate, or its best crossbar triple when
    /// the filter left it none.
    pub slab: Vec<[u32; 3]>,
    /// Usage penalty of each pixel, in sixteenths ([`balance`]): the correction scales a
    /// candidate's distance by (16 + its pixels' penalties) / 16. All zero without balancing.
    pub penalty: Vec<u8>,
    pub stats: LevelStats,
}

/// One exemplar's levels, finest first.
#[derive(Clone, Debug, PartialEq)]
pub struct ExemplarData {
    pub levels: Vec<LevelData>,
}

/// The complete analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct Analysis {
    pub params: AnalysisParams,
    pub border: Border,
    /// Colour channels (1, 3 or 4); the images carry one more when `has_feature`.
    pub color_channels: u32,
    pub has_feature: bool,
    /// One image serves all three axes; only its data is stored.
    pub shared: bool,
    /// 1 when shared, else 3 (Ex, Ey, Ez).
    pub exemplars: Vec<ExemplarData>,
}

/// Progress report: a stage name and how far along the whole analysis is (0..=1).
pub type Progress<'a> = &'a (dyn Fn(&str, f32) + Sync);

impl Analysis {
    /// The data of exemplar `a` (0, 1, 2 = Ex, Ey, Ez).
    pub fn exemplar(&self, a: usize) -> &ExemplarData {
        if self.shared {
            &self.exemplars[0]
        } else {
            &self.exemplars[a]
        }
    }

    pub fn level_count(&self) -> usize {
        self.exemplars[0].levels.len()
    }

    /// Number of 3D candidates of pixel `p` of E_a.
    pub fn candidate_count(&self, a: usize, level: usize, p: usize) -> usize {
        let owner = if self.shared { 0 } else { a };
        self.exemplars[owner].levels[level].counts_3d[p] as usize
    }

    /// The 3D candidates of pixel `p` of E_a, as triples in (Ex, Ey, Ez) order.
    pub fn candidates_3d(&self, a: usize, level: usize, p: usize) -> Vec<[u32; 3]> {
        let owner = if self.shared { 0 } else { a };
        let l = &self.exemplars[owner].levels[level];
        let k = self.params.max_3d as usize;
        let n = l.counts_3d[p] as usize;
        l.candidates_3d[p * k..p * k + n]
            .iter()
            .map(|&t| {
                if self.shared {
                    rotate_from_shared(t, a)
                } else {
                    t
                }
            })
            .collect()
    }

    /// The slab triple of pixel `p` of E_a.
    pub fn slab_triple(&self, a: usize, level: usize, p: usize) -> [u32; 3] {
        let t = self.exemplar(a).levels[level].slab[p];
        if self.shared {
            rotate_from_shared(t, a)
        } else {
            t
        }
    }
}

/// Bring the exemplars to one channel count (the largest; see `Image::with_channels`).
fn unify_channels(images: &[Image]) -> Vec<Image> {
    let target = images.iter().map(|i| i.channels).max().unwrap_or(3);
    images.iter().map(|img| img.with_channels(target)).collect()
}

fn check_input(input: &AnalysisInput) -> Result<()> {
    let n = input.exemplars.len();
    if n != 1 && n != 3 {
        return Err(Error::invalid(
            "exemplars",
            "give one image, or three (Ex, --ey, --ez)",
        ));
    }
    for (img, name) in input.exemplars.iter().zip(&input.names) {
        exemplar::check_exemplar_size(img, name)?;
    }
    let first = &input.exemplars[0];
    for (img, name) in input.exemplars.iter().zip(&input.names).skip(1) {
        if (img.width, img.height) != (first.width, first.height) {
            return Err(Error::invalid(
                name,
                format!(
                    "is {}x{} but the x exemplar is {}x{}; Ex, Ey and Ez must have the same size",
                    img.width, img.height, first.width, first.height
                ),
            ));
        }
    }
    if !input.masks.is_empty() && input.masks.len() != n {
        return Err(Error::invalid(
            "feature masks",
            format!(
                "{} masks for {n} exemplars: give one per exemplar or none",
                input.masks.len()
            ),
        ));
    }
    Ok(())
}

/// Run the analysis, without the usage balancing: its penalties are zero. The balancing runs
/// calibration syntheses, so it belongs to the synthesis layer: `lazy::analyze` runs this and
/// then the balancing, which is what every synthesis reads.
pub fn analyze_unbalanced(
    input: &AnalysisInput,
    params: &AnalysisParams,
    compute: &Compute,
    progress: Progress,
) -> Result<Analysis> {
    params.validate()?;
    check_input(input)?;
    let border = input.border;
    let colours = unify_channels(&input.exemplars);
    let color_channels = colours[0].channels;
    let has_feature = !input.masks.is_empty();
    // Working images: colours plus the feature channel.
    let mut working = Vec::new();
    for (i, img) in colours.iter().enumerate() {
        if has_feature {
            let what = format!("feature mask of {}", input.names[i]);
            let f = feature::feature_channel(&input.masks[i], img, &what, border)?;
            working.push(img.with_extra_channels(&f));
        } else {
            working.push(img.clone());
        }
    }
    let pyramids: Vec<Vec<Image>> = working
        .iter()
        .map(|img| pyramid::gaussian_pyramid(img, ANALYSED_LEVELS, border))
        .collect();
    let shared = pyramids.len() == 1;
    let channels = working[0].channels as usize;
    let mut channel_weight = vec![1.0f32; NEIGHBOURHOOD_PIXELS * channels];
    if has_feature {
        for px in 0..NEIGHBOURHOOD_PIXELS {
            channel_weight[px * channels + channels - 1] = params.feature_weight;
        }
    }

    let mut per_exemplar: Vec<Vec<LevelData>> = vec![Vec::new(); pyramids.len()];
    for level in 0..ANALYSED_LEVELS {
        let base = level as f32 / ANALYSED_LEVELS as f32;
        let step = 1.0 / ANALYSED_LEVELS as f32;
        let say = |what: &str, f: f32| progress(&format!("level {level}: {what}"), base + step * f);
        let images: Vec<&Image> = pyramids.iter().map(|p| &p[level]).collect();

        let timer = std::time::Instant::now();
        let lap =
            |what: &str| tracing::debug!(level, "{what}: {:.3} s", timer.elapsed().as_secs_f64());
        say("PCA and projection", 0.0);
        let mut partial = Vec::new();
        for img in &images {
            let mut vectors =
                Vec::with_capacity(img.pixel_count() * NEIGHBOURHOOD_PIXELS * channels);
            for y in 0..img.height {
                for x in 0..img.width {
                    neighbourhood::gather(img, border, x, y, &mut vectors);
                }
            }
            let basis = pca::fit(
                &vectors,
                NEIGHBOURHOOD_PIXELS * channels,
                params.pca_dims[level] as usize,
                &channel_weight,
                1 << 16,
            )?;
            drop(vectors);
            let projected = compute.project(img, border, &basis)?;
            let bytes = crate::contract::pca::unpack_bytes(&projected, &basis);
            let candidates_2d = kcoherent::candidates(
                &bytes,
                basis.output_dims as usize,
                img.width,
                img.height,
                border,
                params.k2d[level] as usize,
            );
            partial.push((basis, projected, candidates_2d));
        }

        lap("PCA, projection, 2D candidates");
        say("crossbar candidates", 0.3);
        let strips = crossbar::build_strips(&images, border);
        let widths = [0, 1, 2].map(|a| images[if shared { 0 } else { a }].width);
        let sets_to_compute = if shared { 1 } else { 3 };
        let mut results = Vec::new();
        for a in 0..sets_to_compute {
            let pick = |i: usize| if shared { &strips[0] } else { &strips[i] };
            let s = [pick(a), pick(next(a)), pick(next(next(a)))];
            let mut sets = crossbar::candidates(
                s,
                params.strips_per_axis as usize,
                params.crossbar_keep as usize,
            );
            lap("crossbar search");
            let best: Vec<Option<crossbar::RankedTriple>> =
                sets.iter().map(|s| s.first().copied()).collect();
            let mean_best_cb =
                best.iter().flatten().map(|t| t.cb as f64).sum::<f64>() / best.len().max(1) as f64;
            say("coherence filter", 0.6 + 0.1 * a as f32);
            let grid = |i: usize| Grid {
                width: images[i].width,
                height: images[i].height,
            };
            let gi = |i: usize| if shared { grid(0) } else { grid(i) };
            let rounds = coherence::filter(
                &mut sets,
                [gi(a), gi(next(a)), gi(next(next(a)))],
                border,
                params.max_3d as usize,
                params.max_filter_rounds as usize,
            );
            lap("coherence filter");
            let k = params.max_3d as usize;
            let mut triples = vec![[NO_COORD; 3]; sets.len() * k];
            let mut counts = vec![0u8; sets.len()];
            let mut slab = Vec::with_capacity(sets.len());
            for (p, set) in sets.iter().enumerate() {
                counts[p] = set.len() as u8;
                for (j, t) in set.iter().enumerate() {
                    triples[p * k + j] = crossbar::to_triple(a, p, t, widths);
                }
                let slab_source = set
                    .first()
                    .or(best[p].as_ref())
                    .expect("S >= 1 gives a triple");
                slab.push(crossbar::to_triple(a, p, slab_source, widths));
            }
            let stats = LevelStats {
                mean_best_cb,
                filter_rounds: rounds as u32,
            };
            results.push((triples, counts, slab, stats));
        }
        for (i, (basis, projected, candidates_2d)) in partial.into_iter().enumerate() {
            let (candidates_3d, counts_3d, slab, stats) = results[i].clone();
            per_exemplar[i].push(LevelData {
                penalty: vec![0; images[i].pixel_count()],
                image: images[i].clone(),
                pca: basis,
                projected,
                candidates_2d,
                candidates_3d,
                counts_3d,
                slab,
                stats,
            });
        }
    }
    let analysis = Analysis {
        params: params.clone(),
        border,
        color_channels,
        has_feature,
        shared,
        exemplars: per_exemplar
            .into_iter()
            .map(|levels| ExemplarData { levels })
            .collect(),
    };
    progress("analysed", 1.0);
    Ok(analysis)
}

/// Candidate statistics of one exemplar's set at one level (for `inspect`, cf. Fig. 13).
#[derive(Clone, Debug, serde::Serialize)]
pub struct CandidateStats {
    pub mean: f64,
    pub min: u32,
    pub max: u32,
    pub pixels_without: usize,
    pub pixels: usize,
}

pub fn candidate_stats(analysis: &Analysis, a: usize, level: usize) -> CandidateStats {
    let counts = &analysis.exemplar(a).levels[level].counts_3d;
    let counts = if counts.is_empty() {
        &analysis.exemplars[0].levels[level].counts_3d
    } else {
        counts
    };
    CandidateStats {
        mean: counts.iter().map(|&c| c as f64).sum::<f64>() / counts.len().max(1) as f64,
        min: counts.iter().copied().min().unwrap_or(0) as u32,
        max: counts.iter().copied().max().unwrap_or(0) as u32,
        pixels_without: counts.iter().filter(|&&c| c == 0).count(),
        pixels: counts.len(),
    }
}
