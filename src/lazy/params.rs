//! What defines a solid besides its analysis ([`SynthParams`]: seed, jitter, candidate mode,
//! correction passes per level, colour rule, coarse-level cache), with the checks on them.

use crate::analysis::ANALYSED_LEVELS;
use crate::contract::jitter;
use crate::error::{Error, Result};

/// Most correction passes a level may run.
pub const MAX_PASSES: u32 = 8;

/// Correction passes per level, coarsest (l_start) first. The paper runs 2 at every level;
/// fewer passes at a level also shrink the dependency padding every coarser level must
/// synthesize, so the finest level's passes weigh most on the time (BENCHMARKS.md, Quality).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassSchedule(pub [u32; ANALYSED_LEVELS]);

impl PassSchedule {
    pub fn uniform(passes: u32) -> PassSchedule {
        PassSchedule([passes; ANALYSED_LEVELS])
    }

    /// The passes of the levels as plan lengths, coarsest first.
    pub fn levels(&self) -> [usize; ANALYSED_LEVELS] {
        self.0.map(|p| p as usize)
    }
}

/// `2` (every level) or one count per level, coarsest first: `2,2,2,1`.
impl std::str::FromStr for PassSchedule {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        let counts: Vec<u32> = text
            .split(',')
            .map(|t| t.trim().parse::<u32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| format!("expected a count or {ANALYSED_LEVELS} comma-separated counts"))?;
        match counts[..] {
            [n] => Ok(PassSchedule::uniform(n)),
            _ => counts
                .try_into()
                .map(PassSchedule)
                .map_err(|_| format!("expected a count or {ANALYSED_LEVELS} comma-separated counts (coarsest level first)")),
        }
    }
}

impl std::fmt::Display for PassSchedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.iter().all(|&p| p == self.0[0]) {
            return write!(f, "{}", self.0[0]);
        }
        let text: Vec<String> = self.0.iter().map(u32::to_string).collect();
        write!(f, "{}", text.join(","))
    }
}

/// Which candidates the correction searches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum CandidateMode {
    /// Precomputed 3D candidates, two-step search (the paper's method).
    #[cfg_attr(feature = "cli", value(name = "3d"))]
    #[serde(rename = "3d")]
    ThreeD,
    /// Standard k-coherent 2D candidates, each direction searched independently (ablation).
    #[cfg_attr(feature = "cli", value(name = "2d"))]
    #[serde(rename = "2d")]
    TwoD,
}

/// `3d` or `2d`, as `--candidates` spells them.
impl std::str::FromStr for CandidateMode {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        match text {
            "3d" => Ok(CandidateMode::ThreeD),
            "2d" => Ok(CandidateMode::TwoD),
            _ => Err("expected 3d or 2d".into()),
        }
    }
}

impl std::fmt::Display for CandidateMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CandidateMode::ThreeD => "3d",
            CandidateMode::TwoD => "2d",
        })
    }
}

/// Where an output voxel's colour comes from (the solid itself, its triples, is the same): one
/// source for every colour channel, or one per channel ([`ColorSource::PerChannel`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColorSource {
    /// The mean of the voxel's three exemplar pixels (the paper's rule).
    #[default]
    Average,
    /// The voxel's three exemplar pixels weighted by how well each plane's 5x5 neighbourhood of
    /// mean colours fits its exemplar around the pixel (`cpu::colorize`). It reads the
    /// neighbours' mean colours, so a request computes 2 voxels more around its output
    /// ([`ColorSource::reach`]).
    Fitted,
    /// The pixel of Ex (resp. Ey, Ez) at the voxel's coordinate in it: sharper, but only as
    /// consistent across axes as the synthesis made the triple.
    X,
    Y,
    Z,
    /// The mean, given the exemplars' mean colour and contrast back (a mean of three pixels
    /// narrows them) by a per-channel table from a probe solid (`super::color_match`). Starting a
    /// session then synthesizes the probe (64^3 to 128^3, tileable).
    Matched,
    /// One of the above per colour channel, red first (`--color x,y,z`: red from Ex, green from
    /// Ey, blue from Ez); as many as the exemplars have colour channels.
    PerChannel(ChannelSources),
}

/// One colour channel's source in [`ColorSource::PerChannel`]: the single sources of
/// [`ColorSource`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum ChannelSource {
    Average,
    Fitted,
    X,
    Y,
    Z,
    Matched,
}

impl ChannelSource {
    const NAMES: [(&'static str, ChannelSource); 6] = [
        ("average", ChannelSource::Average),
        ("fitted", ChannelSource::Fitted),
        ("matched", ChannelSource::Matched),
        ("x", ChannelSource::X),
        ("y", ChannelSource::Y),
        ("z", ChannelSource::Z),
    ];

    fn name(self) -> &'static str {
        Self::NAMES.iter().find(|(_, s)| *s == self).unwrap().0
    }

    fn parse(name: &str) -> std::result::Result<ChannelSource, String> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == name.trim())
            .map(|&(_, source)| source)
            .ok_or_else(|| {
                format!(
                    "unknown colour source {name:?}: average, fitted, matched, x, y or z, or \
                     one per colour channel separated by commas"
                )
            })
    }

    /// Its code in `ColorizeParams::source`: 0 the mean, a + 1 exemplar a's pixel, 4 the
    /// matched mean, 5 the fitted weighting.
    fn code(self) -> u32 {
        match self {
            ChannelSource::Average => 0,
            ChannelSource::Fitted => 5,
            ChannelSource::X => 1,
            ChannelSource::Y => 2,
            ChannelSource::Z => 3,
            ChannelSource::Matched => 4,
        }
    }
}

/// The sources of [`ColorSource::PerChannel`], red first: `len` of them, the rest unused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ChannelSources {
    pub sources: [ChannelSource; 4],
    pub len: u8,
}

impl ColorSource {
    /// The source of colour channel `c`.
    pub fn channel(self, c: usize) -> ChannelSource {
        match self {
            ColorSource::Average => ChannelSource::Average,
            ColorSource::Fitted => ChannelSource::Fitted,
            ColorSource::X => ChannelSource::X,
            ColorSource::Y => ChannelSource::Y,
            ColorSource::Z => ChannelSource::Z,
            ColorSource::Matched => ChannelSource::Matched,
            ColorSource::PerChannel(list) => list.sources[c],
        }
    }

    /// Whether a channel needs the `matched` table (and so the probe solid).
    pub fn needs_matching(self) -> bool {
        (0..4).any(|c| self.channel(c) == ChannelSource::Matched)
    }

    /// How far (voxels, along every axis) a voxel's colour reads its neighbours' mean colours:
    /// `contract::uniforms::FITTED_REACH` when a channel is [`ChannelSource::Fitted`], else 0 (the other rules
    /// read the voxel alone). Requests compute this much more around their output.
    pub fn reach(self) -> i32 {
        let channels = match self {
            // (A hand-built list longer than its four slots prints its four.)
            ColorSource::PerChannel(list) => (list.len as usize).min(4),
            _ => 1,
        };
        match (0..channels).any(|c| self.channel(c) == ChannelSource::Fitted) {
            true => crate::contract::uniforms::FITTED_REACH,
            false => 0,
        }
    }

    /// `ColorizeParams::source`: colour channel c's [`ChannelSource`] code in bits 4c..4c+3.
    pub fn kernel_code(self) -> u32 {
        (0..4).fold(0, |code, c| code | self.channel(c).code() << (4 * c))
    }
}

impl std::str::FromStr for ColorSource {
    type Err = String;

    /// `average`, `fitted`, `matched`, `x`, `y` or `z`, or 2 to 4 of them separated by commas, one per
    /// colour channel.
    fn from_str(text: &str) -> std::result::Result<ColorSource, String> {
        let names: Vec<&str> = text.split(',').collect();
        match names.len() {
            1 => Ok(match ChannelSource::parse(names[0])? {
                ChannelSource::Average => ColorSource::Average,
                ChannelSource::Fitted => ColorSource::Fitted,
                ChannelSource::X => ColorSource::X,
                ChannelSource::Y => ColorSource::Y,
                ChannelSource::Z => ColorSource::Z,
                ChannelSource::Matched => ColorSource::Matched,
            }),
            2..=4 => {
                let mut sources = [ChannelSource::Average; 4];
                for (slot, name) in sources.iter_mut().zip(&names) {
                    *slot = ChannelSource::parse(name)?;
                }
                Ok(ColorSource::PerChannel(ChannelSources {
                    sources,
                    len: names.len() as u8,
                }))
            }
            n => Err(format!(
                "{n} colour sources: at most 4, one per colour channel"
            )),
        }
    }
}

impl std::fmt::Display for ColorSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let len = match self {
            // (A hand-built list longer than its four slots prints its four.)
            ColorSource::PerChannel(list) => (list.len as usize).min(4),
            _ => 1,
        };
        let names: Vec<&str> = (0..len).map(|c| self.channel(c).name()).collect();
        write!(f, "{}", names.join(","))
    }
}

/// What defines the solid besides the analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthParams {
    pub seed: u64,
    /// Jitter magnitude (0 disables; 1 is the default warp).
    pub jitter: f32,
    pub candidates: CandidateMode,
    /// Correction passes per level (the paper uses 2 at every level).
    pub passes: PassSchedule,
    /// Output colour rule.
    pub color: ColorSource,
    /// Coarse-level cache (paper 6.2): when set, the levels above the finest come from one
    /// tileable solid of this period (finest-level voxels; a multiple of 64), synthesized once
    /// per session and read through the jitter warp; each request then synthesizes only the
    /// finest level. This defines a different (equally deterministic) solid.
    pub coarse_cache: Option<u32>,
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            seed: 0,
            jitter: 1.0,
            candidates: CandidateMode::ThreeD,
            passes: PassSchedule::uniform(2),
            color: ColorSource::Average,
            coarse_cache: None,
        }
    }
}

impl SynthParams {
    pub fn validate(&self) -> Result<()> {
        if !(self.jitter.is_finite() && (0.0..=jitter::MAX_JITTER).contains(&self.jitter)) {
            return Err(Error::invalid(
                format!("--jitter {}", self.jitter),
                format!("must be a number in 0..={}", jitter::MAX_JITTER),
            ));
        }
        if let Some(n) = self.coarse_cache {
            check_coarse_cache(n)?;
        }
        if self.passes.0.iter().any(|&p| p > MAX_PASSES) {
            return Err(Error::invalid(
                format!("--passes {}", self.passes),
                format!(
                    "each level's passes must be 0..={MAX_PASSES} (0 shows the initialization)"
                ),
            ));
        }
        if let ColorSource::PerChannel(list) = self.color {
            if !(1..=4).contains(&list.len) {
                return Err(Error::invalid(
                    "--color",
                    format!("names {} channel sources; a colour has 1 to 4", list.len),
                ));
            }
        }
        Ok(())
    }
}

/// The periods of `levels` levels of a periodic solid whose last level has period `n`,
/// coarsest first (each level half its child's).
pub(super) fn periods_below(n: u32, levels: usize) -> Vec<u32> {
    (0..levels).map(|l| n >> (levels - 1 - l)).collect()
}

/// Refuse a tileable period `n` (finest-level voxels) that the pyramid cannot keep periodic:
/// each level's period is half the next one's, and the correction's brick-local sub-passes
/// (`plan`) need whole 4-voxel bricks in every level's period, so `n` must be a multiple of 32.
/// The l_start period is then whole jitter cells too (`contract::jitter`).
pub fn check_tileable_size(n: u32) -> Result<()> {
    let levels = 1u32 << (ANALYSED_LEVELS - 1);
    let step = 4 * levels;
    if n < step || !n.is_multiple_of(step) {
        return Err(Error::invalid(
            format!("--size {n} with --tileable"),
            format!(
                "must be a multiple of {step} (each of the {ANALYSED_LEVELS} levels halves the \
                 period, and the coarsest needs whole 4-voxel bricks)"
            ),
        ));
    }
    Ok(())
}

/// The periods the coarse-level cache (`--coarse-cache`) can have: multiples of 64 in this range.
pub const COARSE_CACHE_PERIODS: std::ops::RangeInclusive<u32> = 64..=1024;

/// Refuse a coarse-level cache period outside [`COARSE_CACHE_PERIODS`] or not a multiple of 64.
pub fn check_coarse_cache(n: u32) -> Result<()> {
    if !COARSE_CACHE_PERIODS.contains(&n) || !n.is_multiple_of(64) {
        return Err(Error::invalid(
            format!("--coarse-cache {n}"),
            format!("must be a multiple of 64 in {COARSE_CACHE_PERIODS:?}"),
        ));
    }
    Ok(())
}

/// Summaries spell the schedule as `--passes` does (`2`, `2,2,2,1`).
impl serde::Serialize for PassSchedule {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

/// Summaries spell the colour rule as `--color` does (`average`, `x,y,z`).
impl serde::Serialize for ColorSource {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}
