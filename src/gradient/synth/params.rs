//! The parameters of a gradient synthesis: its levels, its slice search, and their limits.

use super::frame;
use super::frame::Field;
use crate::error::{Error, Result};
use crate::gradient::SPACING;

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
    /// both ([`super::crossbar`]: the sets are precomputed per level).
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
    /// sqrt(candidates) lists; see [`super::patches::LevelPatches::nearest`]).
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
