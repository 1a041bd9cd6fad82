//! `solidsynth analyze`, and the input handling shared with the commands that synthesize.

use clap::Args;
use solidsynth::analysis::frame::{self, InputFrame};
use solidsynth::analysis::{self, Analysis, AnalysisInput, AnalysisParams};
use solidsynth::backend::Compute;
use solidsynth::exemplar::{self, Border, Image};
use solidsynth::io::{atomic, ssa};
use solidsynth::Error;
use std::path::PathBuf;
use std::time::Instant;

/// Exemplar inputs: an image (analysed), an .ssa file (loaded), or nothing (built-in exemplar).
#[derive(Args, Debug)]
pub struct InputArgs {
    /// Exemplar image (PNG, JPEG, ...; gray, RGB or RGBA; 8 or 16 bit), used for all three axes
    /// unless --ey and --ez are given; or an .ssa analysis file. Without it, the built-in exemplar.
    pub input: Option<PathBuf>,
    /// Exemplar for the plane orthogonal to y.
    #[arg(long, requires = "ez")]
    pub ey: Option<PathBuf>,
    /// Exemplar for the plane orthogonal to z.
    #[arg(long, requires = "ey")]
    pub ez: Option<PathBuf>,
    /// How the exemplars lie in the three planes, as (column axis, row axis) for x, y, z.
    /// `paper` (default): (y, z), (x, z), (x, y), the paper's coordinate inheritance: the
    /// planes orthogonal to x and y share "up" (z), so layered structures and directional
    /// lighting agree in two of them (better scores, see BENCHMARKS.md); one image is analysed
    /// as three exemplars (about twice the analysis time). `cyclic`: (y, z), (z, x), (x, y),
    /// one image with one shared candidate set.
    #[arg(long, value_enum)]
    pub frame: Option<InputFrame>,
    /// The feature channel's mask: `auto` (each exemplar's luminance split in two by Otsu's
    /// threshold), `edges` (its strong edges: gradient magnitude above Otsu's threshold; for
    /// cells, mortar grids, cracks), `none` (colour only: the paper's plain search), or a mask
    /// image the size of the exemplar (white inside). The signed distance to the mask's
    /// boundary becomes one more channel of the neighbourhoods, so matching keeps the shapes it
    /// outlines (a file named like a keyword is written ./auto).
    #[arg(long, default_value = "auto", value_parser = parse_feature_mask)]
    pub feature_mask: FeatureMask,
    /// Feature mask of --ey (required with --ey when --feature-mask is an image).
    #[arg(long)]
    pub ey_feature_mask: Option<PathBuf>,
    /// Feature mask of --ez.
    #[arg(long)]
    pub ez_feature_mask: Option<PathBuf>,
    /// Weight of the feature channel relative to one colour channel.
    #[arg(long, default_value_t = solidsynth::analysis::DEFAULT_FEATURE_WEIGHT)]
    pub feature_weight: f32,
    /// The exemplars tile (wrap around at the edges). Without it, edges are mirrored so no
    /// neighbourhood straddles the seam of a non-tileable image. The built-in exemplar tiles.
    #[arg(long)]
    pub periodic: bool,
    /// Usage-balancing rounds of the analysis: small calibration solids that find the exemplar
    /// pixels the correction over-uses, which it then penalizes (keeps photographs from washing
    /// out to a few flat pixels). 0: the paper's unmodified search.
    #[arg(long, default_value_t = solidsynth::analysis::balance::DEFAULT_ROUNDS)]
    pub balance_rounds: u32,
    /// Strength of the usage penalty (0..=8).
    #[arg(long, default_value_t = 1.0)]
    pub balance_strength: f32,
    #[command(flatten)]
    pub backend: super::BackendArgs,
}

/// Where the feature channel's masks come from.
#[derive(Clone, Debug, PartialEq)]
pub enum FeatureMask {
    /// [`solidsynth::exemplar::feature::auto_masks`] of the exemplars.
    Auto,
    /// [`solidsynth::exemplar::feature::edge_masks`] of the exemplars.
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
    /// The frame `exemplars` are given in (`frame::resolve_frame`), saying so in the log when a
    /// non-square image defaults to the cyclic one.
    fn frame_of(&self, exemplars: &[Image]) -> solidsynth::Result<InputFrame> {
        let frame = frame::resolve_frame(exemplars, self.frame)?;
        if self.frame.is_none() && frame == InputFrame::Cyclic {
            tracing::info!(
                "non-square exemplar: --frame cyclic (the paper's frame transposes the y exemplar)"
            );
        }
        Ok(frame)
    }

    /// Whether a feature-mask option other than the default was given.
    pub fn feature_mask_given(&self) -> bool {
        self.feature_mask != FeatureMask::Auto
            || self.ey_feature_mask.is_some()
            || self.ez_feature_mask.is_some()
            || self.feature_weight != solidsynth::analysis::DEFAULT_FEATURE_WEIGHT
    }

    fn is_ssa(&self) -> bool {
        self.input
            .as_ref()
            .is_some_and(|p| p.extension().is_some_and(|e| e == "ssa"))
    }

    /// Load the images and masks the arguments name.
    pub fn analysis_input(&self) -> solidsynth::Result<(AnalysisInput, AnalysisParams)> {
        let mut exemplars = Vec::new();
        let mut names = Vec::new();
        let mut border = if self.periodic {
            Border::Wrap
        } else {
            Border::Mirror
        };
        match &self.input {
            Some(p) => {
                exemplars.push(exemplar::load_image(p, "exemplar")?);
                names.push(format!("exemplar {}", p.display()));
            }
            None => {
                if self.ey.is_some() {
                    return Err(Error::invalid("--ey", "needs the x exemplar INPUT too"));
                }
                exemplars.push(exemplar::default_exemplar());
                names.push("built-in exemplar".into());
                border = Border::Wrap;
            }
        }
        if let (Some(ey), Some(ez)) = (&self.ey, &self.ez) {
            exemplars.push(exemplar::load_image(ey, "--ey")?);
            names.push(format!("--ey {}", ey.display()));
            exemplars.push(exemplar::load_image(ez, "--ez")?);
            names.push(format!("--ez {}", ez.display()));
        }
        if self.feature_mask == FeatureMask::None
            && self.feature_weight != solidsynth::analysis::DEFAULT_FEATURE_WEIGHT
        {
            return Err(Error::invalid(
                "--feature-weight",
                "has no effect with --feature-mask none (there is no feature channel)",
            ));
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
        let mut masks = Vec::new();
        if given > 0 {
            if given != exemplars.len() || flags[0].1.is_none() {
                return Err(Error::invalid(
                    "feature masks",
                    if exemplars.len() == 3 {
                        "give --feature-mask, --ey-feature-mask and --ez-feature-mask images together"
                    } else {
                        "give --feature-mask only (one exemplar)"
                    },
                ));
            }
            for (flag, path) in flags.iter().take(exemplars.len()) {
                masks.push(exemplar::load_image(path.as_ref().unwrap(), flag)?);
            }
        } else if self.feature_mask == FeatureMask::Auto {
            masks = exemplar::feature::auto_masks(&exemplars);
        } else if self.feature_mask == FeatureMask::Edges {
            masks = exemplar::feature::edge_masks(&exemplars, border);
        }
        // In the crate's frame: with the paper's, one image (and its mask) becomes three
        // exemplars, Ey transposed.
        let frame = self.frame_of(&exemplars)?;
        if frame == InputFrame::Paper {
            if names.len() == 1 {
                names = vec![names[0].clone(), names[0].clone(), names[0].clone()];
            }
            names[1] = format!("{} (transposed: --frame paper)", names[1]);
        }
        let exemplars = frame::to_crate_frame(exemplars, frame);
        let masks = if masks.is_empty() {
            masks
        } else {
            frame::to_crate_frame(masks, frame)
        };
        let params = AnalysisParams {
            feature_weight: self.feature_weight,
            balance_rounds: self.balance_rounds,
            balance_strength: self.balance_strength,
            ..Default::default()
        };
        Ok((
            AnalysisInput {
                exemplars,
                masks,
                border,
                names,
            },
            params,
        ))
    }
}

/// The analysis of the inputs: loaded from an .ssa, taken from the cache, or computed (and
/// cached). The cache key hashes the decoded pixels, masks, border and parameters.
pub fn load_or_analyze(
    args: &InputArgs,
    compute: &Compute,
    quiet: bool,
) -> solidsynth::Result<Analysis> {
    if args.is_ssa() {
        if args.ey.is_some() || args.feature_mask_given() || args.frame.is_some() {
            return Err(Error::invalid(
                "--ey/--frame/--feature-mask/--feature-weight",
                "are analysis inputs; an .ssa file already holds them",
            ));
        }
        if args.balance_rounds != analysis::balance::DEFAULT_ROUNDS || args.balance_strength != 1.0
        {
            return Err(Error::invalid(
                "--balance-rounds/--balance-strength",
                "are analysis parameters; an .ssa file already holds them",
            ));
        }
        return ssa::load(args.input.as_ref().unwrap());
    }
    let (input, params) = args.analysis_input()?;
    let key = cache_key(&input, &params);
    let cache = cache_dir().map(|d| d.join(format!("{key:016x}.ssa")));
    if let Some(path) = &cache {
        if let Ok(a) = ssa::load(path) {
            tracing::info!("analysis from cache {}", path.display());
            return Ok(a);
        }
    }
    let bar = super::progress_bar(quiet);
    let report = |stage: &str, f: f32| {
        bar.set_position((f * 1000.0) as u64);
        bar.set_message(format!("analysis {stage}"));
    };
    let a = solidsynth::lazy::analyze(&input, &params, compute, &report)?;
    bar.finish_and_clear();
    if let Some(path) = &cache {
        let saved = path
            .parent()
            .map(std::fs::create_dir_all)
            .transpose()
            .ok()
            .and_then(|_| ssa::save(&a, path).ok());
        if saved.is_none() {
            tracing::warn!("could not cache the analysis at {}", path.display());
        }
    }
    Ok(a)
}

fn cache_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("SOLIDSYNTH_CACHE_DIR") {
        return Some(PathBuf::from(d));
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("solidsynth"))
}

fn cache_key(input: &AnalysisInput, params: &AnalysisParams) -> u64 {
    let mut h = crc32fast::Hasher::new();
    let mut h2 = crc32fast::Hasher::new_with_initial(0x5EED);
    let mut feed = |b: &[u8]| {
        h.update(b);
        h2.update(b);
    };
    feed(&ssa::FORMAT_VERSION.to_le_bytes());
    feed(&analysis::ALGORITHM_REVISION.to_le_bytes());
    feed(format!("{params:?}{:?}", input.border).as_bytes());
    for img in input.exemplars.iter().chain(&input.masks) {
        feed(
            &[img.width, img.height, img.channels]
                .map(u32::to_le_bytes)
                .concat(),
        );
        feed(&img.pixels);
    }
    ((h.finalize() as u64) << 32) | h2.finalize() as u64
}

#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Output .ssa file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: AnalyzeArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&args.output, "-o")?;
    if args.input.is_ssa() {
        anyhow::bail!(Error::invalid(
            "input",
            "is already an .ssa analysis; give an image"
        ));
    }
    let start = Instant::now();
    let (input, params) = args.input.analysis_input()?;
    let compute = args.input.backend.open()?;
    let bar = super::progress_bar(quiet || args.json);
    let report = |stage: &str, f: f32| {
        bar.set_position((f * 1000.0) as u64);
        bar.set_message(stage.to_string());
    };
    let result = solidsynth::lazy::analyze(&input, &params, &compute, &report)?;
    bar.finish_and_clear();
    let bytes = ssa::to_bytes(&result);
    atomic::write_file(&args.output, &bytes)?;
    let seconds = start.elapsed().as_secs_f64();
    let finest = &result.exemplars[0].levels[0].image;
    if args.json {
        let summary = serde_json::json!({
            "output": args.output, "width": finest.width, "height": finest.height,
            "shared": result.shared, "bytes": bytes.len(), "seconds": seconds,
            "peak_rss_bytes": solidsynth::util::memory::peak_rss_bytes(),
            "backend": compute.describe(),
        });
        println!("{summary}");
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
