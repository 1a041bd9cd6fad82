//! `solidsynth analyze`.

use clap::Args;
use solidsynth::analysis::{self, AnalysisInput, AnalysisParams};
use solidsynth::exemplar::{self, Border};
use solidsynth::io::{atomic, ssa};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    /// Exemplar image (PNG, JPEG, ...; gray, RGB or RGBA; 8 or 16 bit). Used for all three axes
    /// unless --ey and --ez are given. Without it, the built-in exemplar.
    pub image: Option<PathBuf>,
    /// Exemplar for the plane orthogonal to y.
    #[arg(long, requires = "ez")]
    pub ey: Option<PathBuf>,
    /// Exemplar for the plane orthogonal to z.
    #[arg(long, requires = "ey")]
    pub ez: Option<PathBuf>,
    /// Mask (same size as the exemplar) whose boundary distance becomes a feature channel.
    #[arg(long)]
    pub feature_mask: Option<PathBuf>,
    /// Feature mask of --ey (required with --ey when --feature-mask is given).
    #[arg(long)]
    pub ey_feature_mask: Option<PathBuf>,
    /// Feature mask of --ez.
    #[arg(long)]
    pub ez_feature_mask: Option<PathBuf>,
    /// Weight of the feature channel relative to one colour channel.
    #[arg(long, default_value_t = 1.0)]
    pub feature_weight: f32,
    /// The exemplars tile (wrap around at the edges). Without it, edges are mirrored so no
    /// neighbourhood straddles the seam of a non-tileable image.
    #[arg(long)]
    pub periodic: bool,
    /// Output .ssa file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub backend: super::BackendArgs,
}

pub fn run(args: AnalyzeArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&args.output, "-o")?;
    let start = Instant::now();
    let mut exemplars = Vec::new();
    let mut names = Vec::new();
    match &args.image {
        Some(p) => {
            exemplars.push(exemplar::load_image(p, "exemplar")?);
            names.push(format!("exemplar {}", p.display()));
        }
        None => {
            if args.ey.is_some() {
                anyhow::bail!(solidsynth::Error::invalid(
                    "--ey",
                    "needs the x exemplar IMAGE too"
                ));
            }
            exemplars.push(exemplar::default_exemplar());
            names.push("built-in exemplar".into());
        }
    }
    if let (Some(ey), Some(ez)) = (&args.ey, &args.ez) {
        exemplars.push(exemplar::load_image(ey, "--ey")?);
        names.push(format!("--ey {}", ey.display()));
        exemplars.push(exemplar::load_image(ez, "--ez")?);
        names.push(format!("--ez {}", ez.display()));
    }
    let mut masks = Vec::new();
    let mask_flags = [
        ("--feature-mask", &args.feature_mask),
        ("--ey-feature-mask", &args.ey_feature_mask),
        ("--ez-feature-mask", &args.ez_feature_mask),
    ];
    let given: Vec<_> = mask_flags.iter().filter(|(_, p)| p.is_some()).collect();
    if !given.is_empty() {
        if given.len() != exemplars.len() || mask_flags[0].1.is_none() {
            anyhow::bail!(solidsynth::Error::invalid(
                "feature masks",
                format!(
                    "give one mask per exemplar: --feature-mask{}",
                    if exemplars.len() == 3 {
                        ", --ey-feature-mask and --ez-feature-mask"
                    } else {
                        " only"
                    }
                ),
            ));
        }
        for (flag, path) in mask_flags.iter().take(exemplars.len()) {
            let path = path.as_ref().unwrap();
            masks.push(exemplar::load_image(path, flag)?);
        }
    }
    let input = AnalysisInput {
        exemplars,
        masks,
        border: if args.periodic {
            Border::Wrap
        } else {
            Border::Mirror
        },
        names,
    };
    let params = AnalysisParams {
        feature_weight: args.feature_weight,
        ..Default::default()
    };
    let compute = args.backend.open()?;
    let bar = super::progress_bar(quiet || args.json);
    let report = |stage: &str, f: f32| {
        bar.set_position((f * 1000.0) as u64);
        bar.set_message(stage.to_string());
    };
    let result = analysis::analyze(&input, &params, &compute, &report)?;
    bar.finish_and_clear();
    let bytes = ssa::to_bytes(&result);
    atomic::write_file(&args.output, &bytes)?;
    let seconds = start.elapsed().as_secs_f64();
    let finest = &result.exemplars[0].levels[0].image;
    if args.json {
        let summary = serde_json::json!({
            "output": args.output,
            "width": finest.width,
            "height": finest.height,
            "shared": result.shared,
            "bytes": bytes.len(),
            "seconds": seconds,
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
