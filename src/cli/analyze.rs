//! `solidsynth analyze`, and the input handling shared with the commands that synthesize.

use crate::analysis::frame::InputFrame;
use crate::analysis::{self, Analysis};
use crate::backend::Compute;
use crate::exemplar;
use crate::io::{atomic, ssa};
use crate::solid::{AnalysisCache, ExemplarInput, FeatureMasks};
use crate::{Error, Solid, SolidBuilder};
use clap::Args;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// Exemplar inputs: an image (analysed), an .ssa file (loaded), or nothing (built-in exemplar).
#[derive(Args, Debug)]
#[command(next_help_heading = "Input and analysis")]
pub struct InputArgs {
    /// Exemplar image (PNG, JPEG, ...; gray, RGB or RGBA; 8 or 16 bit), used for all three axes
    /// unless --ey and --ez are given; or an .ssa analysis file. Without it, the built-in exemplar.
    pub input: Option<PathBuf>,
    /// Exemplar for the plane orthogonal to y.
    #[arg(help_heading = "Input and analysis", long, requires = "ez")]
    pub ey: Option<PathBuf>,
    /// Exemplar for the plane orthogonal to z.
    #[arg(help_heading = "Input and analysis", long, requires = "ey")]
    pub ez: Option<PathBuf>,
    /// How the exemplars lie in the three planes, as (column axis, row axis) for x, y, z.
    /// `paper` (default): (y, z), (x, z), (x, y), the paper's coordinate inheritance: the
    /// planes orthogonal to x and y share "up" (z), so layered structures and directional
    /// lighting agree in two of them (better scores, see BENCHMARKS.md); one image is analysed
    /// as three exemplars (about twice the analysis time). `cyclic`: (y, z), (z, x), (x, y),
    /// one image with one shared candidate set.
    #[arg(help_heading = "Input and analysis", long, value_enum)]
    pub frame: Option<InputFrame>,
    /// The feature channel's mask: `auto` (each exemplar's luminance split in two by Otsu's
    /// threshold), `edges` (its strong edges: gradient magnitude above Otsu's threshold; for
    /// cells, mortar grids, cracks), `none` (colour only: the paper's plain search), or a mask
    /// image the size of the exemplar (white inside). The signed distance to the mask's
    /// boundary becomes one more channel of the neighbourhoods, so matching keeps the shapes it
    /// outlines (a file named like a keyword is written ./auto).
    #[arg(help_heading = "Input and analysis", long, default_value = "auto", value_parser = parse_feature_mask)]
    pub feature_mask: FeatureMask,
    /// Feature mask of --ey (required with --ey when --feature-mask is an image).
    #[arg(help_heading = "Input and analysis", long)]
    pub ey_feature_mask: Option<PathBuf>,
    /// Feature mask of --ez.
    #[arg(help_heading = "Input and analysis", long)]
    pub ez_feature_mask: Option<PathBuf>,
    /// Weight of the feature channel relative to one colour channel.
    #[arg(help_heading = "Input and analysis", long, default_value_t = crate::analysis::DEFAULT_FEATURE_WEIGHT)]
    pub feature_weight: f32,
    /// The exemplars tile (wrap around at the edges). Without it, edges are mirrored so no
    /// neighbourhood straddles the seam of a non-tileable image. The built-in exemplar tiles.
    #[arg(help_heading = "Input and analysis", long)]
    pub periodic: bool,
    /// Usage-balancing rounds of the analysis: small calibration solids that find the exemplar
    /// pixels the correction over-uses, which it then penalizes (keeps photographs from washing
    /// out to a few flat pixels). 0: the paper's unmodified search.
    #[arg(help_heading = "Input and analysis", long, default_value_t = crate::analysis::balance::DEFAULT_ROUNDS, value_parser = super::whole_number_in::<0, { crate::analysis::balance::MAX_ROUNDS }>)]
    pub balance_rounds: u32,
    /// Strength of the usage penalty (0..=8).
    #[arg(help_heading = "Input and analysis", long, default_value_t = 1.0)]
    pub balance_strength: f32,
    #[command(flatten)]
    pub backend: super::BackendArgs,
}

/// Where the feature channel's masks come from.
#[derive(Clone, Debug, PartialEq)]
pub enum FeatureMask {
    /// [`crate::exemplar::feature::auto_masks`] of the exemplars.
    Auto,
    /// [`crate::exemplar::feature::edge_masks`] of the exemplars.
    Edges,
    /// No feature channel.
    None,
    /// A mask image (with --ey-feature-mask and --ez-feature-mask for three exemplars).
    File(PathBuf),
}

fn parse_feature_mask(s: &str) -> Result<FeatureMask, String> {
    Ok(match s {
        "auto" => FeatureMask::Auto,
        "edges" => FeatureMask::Edges,
        "none" => FeatureMask::None,
        "" => return Err("expected auto, edges, none or a mask image".into()),
        path => FeatureMask::File(path.into()),
    })
}

impl InputArgs {
    /// The analysis flags given other than at their defaults, by name: what an `.ssa` input
    /// (which holds its analysis) or a missing INPUT (`serve` analyses the built-in exemplar
    /// its own way) refuses.
    pub fn analysis_flags_given(&self) -> Vec<&'static str> {
        let given = [
            ("--ey", self.ey.is_some()),
            ("--frame", self.frame.is_some()),
            ("--feature-mask", self.feature_mask != FeatureMask::Auto),
            ("--ey-feature-mask", self.ey_feature_mask.is_some()),
            ("--ez-feature-mask", self.ez_feature_mask.is_some()),
            (
                "--feature-weight",
                self.feature_weight != crate::analysis::DEFAULT_FEATURE_WEIGHT,
            ),
            ("--periodic", self.periodic),
            (
                "--balance-rounds",
                self.balance_rounds != analysis::balance::DEFAULT_ROUNDS,
            ),
            ("--balance-strength", self.balance_strength != 1.0),
        ];
        given
            .into_iter()
            .filter_map(|(flag, on)| on.then_some(flag))
            .collect()
    }

    fn is_ssa(&self) -> bool {
        self.input
            .as_ref()
            .is_some_and(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("ssa")))
    }

    /// The exemplar-side settings the arguments name, images and masks loaded.
    pub fn exemplar_input(&self) -> crate::Result<ExemplarInput> {
        let mut images = Vec::new();
        let mut names = Vec::new();
        match &self.input {
            Some(p) => {
                images.push(exemplar::load_image(p, "exemplar")?);
                names.push(format!("exemplar {}", p.display()));
            }
            None if self.ey.is_some() => {
                return Err(Error::invalid("--ey", "needs the x exemplar INPUT too"));
            }
            None => {}
        }
        if let (Some(ey), Some(ez)) = (&self.ey, &self.ez) {
            images.push(exemplar::load_image(ey, "--ey")?);
            names.push(format!("--ey {}", ey.display()));
            images.push(exemplar::load_image(ez, "--ez")?);
            names.push(format!("--ez {}", ez.display()));
        }
        let file = match &self.feature_mask {
            FeatureMask::File(p) => Some(p.clone()),
            _ => None,
        };
        let flags = [
            ("--feature-mask", &file),
            ("--ey-feature-mask", &self.ey_feature_mask),
            ("--ez-feature-mask", &self.ez_feature_mask),
        ];
        let given = flags.iter().filter(|(_, p)| p.is_some()).count();
        let feature_masks = if given > 0 {
            let exemplars = images.len().max(1);
            if given != exemplars || flags[0].1.is_none() {
                return Err(Error::invalid(
                    "feature masks",
                    if exemplars == 3 {
                        "give --feature-mask, --ey-feature-mask and --ez-feature-mask images together"
                    } else {
                        "give --feature-mask only (one exemplar)"
                    },
                ));
            }
            let mut masks = Vec::new();
            for (flag, path) in flags.iter().take(exemplars) {
                masks.push(exemplar::load_image(path.as_ref().unwrap(), flag)?);
            }
            FeatureMasks::Images(masks)
        } else {
            match self.feature_mask {
                FeatureMask::Edges => FeatureMasks::Edges,
                FeatureMask::None => FeatureMasks::None,
                _ => FeatureMasks::Auto,
            }
        };
        Ok(ExemplarInput {
            images,
            names,
            frame: self.frame,
            feature_masks,
            feature_weight: self.feature_weight,
            periodic: self.periodic,
            balance_rounds: self.balance_rounds,
            balance_strength: self.balance_strength,
        })
    }

    /// The analysis side of a solid's builder: an .ssa file loaded, or the exemplars with the
    /// user's analysis cache.
    pub fn builder(&self) -> crate::Result<SolidBuilder> {
        let builder = Solid::builder().backend(self.backend.backend, self.backend.gpu_options());
        if self.is_ssa() {
            let given = self.analysis_flags_given();
            if !given.is_empty() {
                return Err(Error::invalid(
                    given.join(" "),
                    "analysis settings; an .ssa file already holds them",
                ));
            }
            return Ok(builder.analysis(ssa::load(self.input.as_ref().unwrap())?));
        }
        Ok(builder
            .exemplar_input(self.exemplar_input()?)
            .cache(AnalysisCache::user_default()))
    }
}

/// The analysis of the inputs, on `compute`: loaded from an .ssa, taken from the cache, or
/// computed (and cached) with a progress bar.
pub fn load_or_analyze(
    args: &InputArgs,
    compute: &Compute,
    quiet: bool,
) -> crate::Result<Arc<Analysis>> {
    analyze_with(args.builder()?, compute, quiet)
}

/// The backend the flags name, and the analysis of the inputs on it ([`load_or_analyze`]). The
/// inputs are read first, so that a missing or damaged file is reported before a GPU is opened.
pub fn open_and_analyze(args: &InputArgs, quiet: bool) -> crate::Result<(Compute, Arc<Analysis>)> {
    let builder = args.builder()?;
    let compute = args.backend.open()?;
    let analysis = analyze_with(builder, &compute, quiet)?;
    Ok((compute, analysis))
}

fn analyze_with(
    builder: SolidBuilder,
    compute: &Compute,
    quiet: bool,
) -> crate::Result<Arc<Analysis>> {
    let bar = super::progress_bar(quiet);
    let shown = bar.clone();
    let builder = builder.progress(move |stage: &str, f: f32| {
        shown.report(stage, f);
    });
    let a = builder.analyze_on(compute)?;
    bar.finish_and_clear();
    Ok(a)
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Output")]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Output .ssa file.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

pub fn run(args: AnalyzeArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&args.output, "-o")?;
    atomic::check_output_extension(&args.output, "-o", "an analysis", &["ssa"])?;
    if args.input.is_ssa() {
        anyhow::bail!(Error::invalid(
            "input",
            "is already an .ssa analysis; give an image"
        ));
    }
    let start = Instant::now();
    // Analysed afresh (not from the cache): `analyze` is how a user makes the file.
    let bar = super::progress_bar(quiet || args.json);
    let shown = bar.clone();
    let builder = Solid::builder()
        .backend(args.input.backend.backend, args.input.backend.gpu_options())
        .exemplar_input(args.input.exemplar_input()?)
        .progress(move |stage: &str, f: f32| {
            shown.report(stage, f);
        });
    let compute = builder.open_compute()?;
    let result = builder.analyze_on(&compute)?;
    bar.finish_and_clear();
    let bytes = ssa::to_bytes(&result);
    atomic::write_file(&args.output, &bytes)?;
    let seconds = start.elapsed().as_secs_f64();
    let finest = &result.exemplars[0].levels[0].image;
    if args.json {
        super::output::print_summary(&AnalyzeSummary {
            output: &args.output,
            width: finest.width,
            height: finest.height,
            shared: result.shared,
            bytes: bytes.len(),
            seconds,
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
            backend: compute.describe(),
        });
    } else if !quiet {
        eprintln!(
            "analysed {}x{} ({}) in {:.2} s -> {} ({:.1} MiB)",
            finest.width,
            finest.height,
            if result.shared {
                "one image for all axes"
            } else {
                "three images"
            },
            seconds,
            args.output.display(),
            bytes.len() as f64 / (1 << 20) as f64
        );
    }
    Ok(())
}

/// `analyze --json`.
#[derive(serde::Serialize)]
struct AnalyzeSummary<'a> {
    output: &'a std::path::Path,
    /// The finest level's size.
    width: u32,
    height: u32,
    /// One image analysed for all three axes.
    shared: bool,
    bytes: usize,
    seconds: f64,
    peak_rss_bytes: Option<u64>,
    backend: String,
}
