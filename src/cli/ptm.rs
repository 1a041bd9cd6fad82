//! `solidsynth ptm ...`: relightable texture synthesis with polynomial texture maps (capture,
//! fit, synthesize, relight).

use super::output::print_summary;
use crate::io::atomic;
use crate::ptm::quilt::{Boundary, QuiltParams, SearchMethod};
use crate::ptm::search::Tolerance;
use crate::ptm::Lighting;
use crate::ptm::{capture, fit, format, relight, PtmFormat};
use crate::Error;
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum PtmCommand {
    /// Write a synthetic capture: images of a procedural surface under N lights, and lights.lp.
    #[command(after_help = super::help::PTM_CAPTURE)]
    Capture(CaptureArgs),
    /// Fit a PTM (least squares per pixel) to a capture directory.
    #[command(after_help = super::help::PTM_FIT)]
    Fit(FitArgs),
    /// Synthesize a larger PTM by block quilting over reflectance functions.
    #[command(after_help = super::help::PTM_SYNTH)]
    Synth(SynthArgs),
    /// Render a PTM under a light (or a ring of lights: a contact sheet) as a PNG.
    #[command(after_help = super::help::PTM_RELIGHT)]
    Relight(RelightArgs),
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Capture")]
pub struct CaptureArgs {
    /// Image side in pixels.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(16..=2048))]
    pub size: u32,
    /// Number of images (light directions), at least 6.
    #[arg(long, default_value_t = 24)]
    pub lights: u32,
    /// Seed of the procedural surface.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output directory (new or empty).
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Fit")]
pub struct FitArgs {
    /// Capture directory: images and a light file (lights.lp, lights.json or one *.lp).
    pub dir: PathBuf,
    /// The light file, if not in the directory.
    #[arg(long)]
    pub lights: Option<PathBuf>,
    /// LRGB: one luminance polynomial and a colour per pixel; RGB: a polynomial per channel.
    #[arg(long, value_enum, default_value = "lrgb")]
    pub format: PtmFormat,
    /// Output .ptm.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Quilting")]
pub struct SynthArgs {
    /// Source .ptm.
    pub input: PathBuf,
    /// Output side in pixels.
    #[arg(long, default_value_t = 512)]
    pub size: u32,
    /// Block side in pixels.
    #[arg(long, default_value_t = 32)]
    pub block: u32,
    /// Overlap between neighbouring blocks in pixels.
    #[arg(long, default_value_t = 6)]
    pub overlap: u32,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Blocks within this fraction of the best neighbourhood distance are equally likely.
    #[arg(long, default_value_t = 0.1)]
    pub tolerance: f64,
    /// Seams: minimum-error cut or alpha blend.
    #[arg(long, value_enum, default_value = "cut")]
    pub boundary: Boundary,
    /// Neighbourhood search (identical results; exact-projection is faster).
    #[arg(long, value_enum, default_value = "exact-projection")]
    pub search: SearchMethod,
    /// Output .ptm.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Lighting")]
pub struct RelightArgs {
    /// Input .ptm.
    pub input: PathBuf,
    /// Light direction LU,LV (its projection on the image plane; LU^2 + LV^2 <= 1).
    #[arg(
        help_heading = "Lighting",
        long,
        allow_hyphen_values = true,
        conflicts_with = "sweep"
    )]
    pub light: Option<String>,
    /// Instead: a contact sheet of N lights in a ring at --elevation.
    #[arg(help_heading = "Lighting", long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub sweep: Option<u32>,
    /// Elevation of the --sweep ring above the surface, degrees (default 35).
    #[arg(help_heading = "Lighting", long)]
    pub elevation: Option<f64>,
    /// Strength of a Blinn-Phong highlight around the PTM's normals (0: none).
    #[arg(help_heading = "Lighting", long, default_value_t = 0.0)]
    pub specular: f32,
    #[command(flatten)]
    pub backend: super::BackendArgs,
    /// Output PNG.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

/// Refuse an output path that names an input file (we never overwrite inputs).
fn check_not_input(output: &Path, input: &Path) -> crate::Result<()> {
    if let (Ok(a), Ok(b)) = (output.canonicalize(), input.canonicalize()) {
        if a == b {
            return Err(Error::invalid(
                format!("-o {}", output.display()),
                "is the input file; choose another output",
            ));
        }
    }
    Ok(())
}

fn parse_light(text: &str) -> crate::Result<(f32, f32)> {
    let bad = || {
        Error::invalid(
            format!("--light {text}"),
            "expected LU,LV with LU^2 + LV^2 <= 1 (e.g. 0.5,-0.3)",
        )
    };
    let v: Vec<f32> = text
        .split(',')
        .map(|p| p.trim().parse::<f32>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [u, v] if u.is_finite() && v.is_finite() && u * u + v * v <= 1.0 + 1e-6 => Ok((*u, *v)),
        _ => Err(bad()),
    }
}

fn capture_cmd(a: CaptureArgs, quiet: bool) -> anyhow::Result<()> {
    if (a.lights as usize) < capture::MIN_IMAGES || a.lights > 1000 {
        return Err(Error::invalid(
            format!("--lights {}", a.lights),
            format!(
                "must be {}..=1000 (a PTM has 6 coefficients)",
                capture::MIN_IMAGES
            ),
        )
        .into());
    }
    let out = &a.output;
    atomic::check_output_dir(out, "-o")?;
    let start = Instant::now();
    let cap = capture::synthetic(a.size, a.lights as usize, a.seed);
    // Written into a hidden sibling directory, then renamed: the capture appears whole or not
    // at all (rename replaces an empty directory).
    let mut outputs = atomic::Outputs::new();
    let staging = outputs.directory(out)?;
    capture::save(&cap, &staging)?;
    outputs.commit()?;
    if a.json {
        print_summary(&CaptureSummary {
            output: out,
            images: a.lights,
            size: a.size,
            seed: a.seed,
            seconds: start.elapsed().as_secs_f64(),
        });
    } else if !quiet {
        eprintln!(
            "captured {} images of {}x{} in {:.2} s -> {}",
            a.lights,
            a.size,
            a.size,
            start.elapsed().as_secs_f64(),
            out.display()
        );
    }
    Ok(())
}

fn fit_cmd(a: FitArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&a.output, "-o")?;
    // The capture's own files are inputs the command line does not name.
    let inputs = capture::input_files(&a.dir, a.lights.as_deref())?;
    atomic::check_output_not_among(&a.output, "-o", &inputs)?;
    atomic::check_output_extension(&a.output, "-o", "a PTM", &["ptm"])?;
    let start = Instant::now();
    let cap = capture::load(&a.dir, a.lights.as_deref())?;
    let what = format!("capture {}", a.dir.display());
    let ptm = fit::fit(&cap, a.format, &what)?;
    let rms = fit::rms_error(&cap, &ptm);
    format::save(&a.output, &ptm)?;
    let secs = start.elapsed().as_secs_f64();
    if a.json {
        print_summary(&FitSummary {
            output: &a.output,
            images: cap.images.len(),
            width: ptm.width,
            height: ptm.height,
            format: ptm.format.header_name(),
            rms_error_levels: rms,
            seconds: secs,
        });
    } else if !quiet {
        eprintln!(
            "fitted a {}x{} {} to {} images in {secs:.2} s: RMS error {rms:.2} levels -> {}",
            ptm.width,
            ptm.height,
            ptm.format.header_name(),
            cap.images.len(),
            a.output.display()
        );
    }
    Ok(())
}

fn synth_cmd(a: SynthArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&a.output, "-o")?;
    atomic::check_output_extension(&a.output, "-o", "a PTM", &["ptm"])?;
    check_not_input(&a.output, &a.input)?;
    if !(0.0..=10.0).contains(&a.tolerance) {
        return Err(
            Error::invalid(format!("--tolerance {}", a.tolerance), "must be 0..=10").into(),
        );
    }
    let src = format::load(&a.input)?;
    crate::ptm::quilt::check_source(&src, &a.input.display().to_string())?;
    let params = QuiltParams {
        width: a.size,
        height: a.size,
        block: a.block,
        overlap: a.overlap,
        seed: a.seed,
        tolerance: Tolerance {
            permille: (a.tolerance * 1000.0).round() as u32,
        },
        boundary: a.boundary,
        search: a.search,
    };
    params.validate(&src)?;
    let bar = super::progress_bar(quiet);
    bar.set_message("synthesizing blocks");
    let start = Instant::now();
    let (out, report) = crate::ptm::quilt::synthesize(&src, &params, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    format::save(&a.output, &out)?;
    let st = &report.stats;
    let survivors: Vec<f64> = st
        .survivors
        .iter()
        .map(|&s| s as f64 / st.candidates.max(1) as f64)
        .collect();
    if a.json {
        use clap::ValueEnum;
        let search = a
            .search
            .to_possible_value()
            .expect("every method has a flag name");
        print_summary(&QuiltSummary {
            output: &a.output,
            size: a.size,
            blocks: [report.blocks.0, report.blocks.1],
            seconds: secs,
            search: search.get_name(),
            surviving_fraction_per_stage: survivors,
            exact_distances_per_query: st.exact as f64 / st.queries.max(1) as f64,
        });
    } else if !quiet {
        eprintln!(
            "synthesized {0}x{0} from {1}x{2} ({3}x{4} blocks of {5}) in {secs:.2} s -> {6}",
            a.size,
            src.width,
            src.height,
            report.blocks.0,
            report.blocks.1,
            a.block,
            a.output.display()
        );
        if st.queries > 0 {
            eprintln!(
                "projection search: fraction of candidates left after each stage (8, 16, 32 kernels) {:?}; {:.1} exact distances per query (of {}), {:.1} of them within the tolerance",
                survivors.iter().map(|f| format!("{f:.4}")).collect::<Vec<_>>(),
                st.exact as f64 / st.queries as f64,
                st.candidates / st.queries,
                // (The first block has no neighbourhood: all candidates are "within".)
                report.within[1..].iter().map(|&w| w as f64).sum::<f64>() / st.queries as f64
            );
        }
    }
    Ok(())
}

fn relight_cmd(a: RelightArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_png_output(&a.output, "-o")?;
    check_not_input(&a.output, &a.input)?;
    if !(a.specular.is_finite() && (0.0..=100.0).contains(&a.specular)) {
        return Err(Error::invalid(format!("--specular {}", a.specular), "must be 0..=100").into());
    }
    // Checked here, not with clap's `requires = "sweep"`: clap waives a requirement that
    // conflicts with an argument given, and --sweep conflicts with --light.
    if a.elevation.is_some() && a.sweep.is_none() {
        return Err(Error::invalid(
            "--elevation",
            "sets the --sweep ring's elevation: give --sweep N with it",
        )
        .into());
    }
    let elevation = a.elevation.unwrap_or(35.0);
    if !(0.0..=90.0).contains(&elevation) {
        return Err(Error::invalid(format!("--elevation {elevation}"), "must be 0..=90").into());
    }
    let single = match (&a.light, a.sweep) {
        (Some(l), None) => Some(parse_light(l)?),
        (None, Some(_)) => None,
        _ => {
            return Err(Error::invalid("--light / --sweep", "give one of them").into());
        }
    };
    let ptm = format::load(&a.input)?;
    let compute = a.backend.open()?;
    let start = Instant::now();
    let img = match single {
        Some((lu, lv)) => {
            let light = Lighting {
                lu,
                lv,
                specular: a.specular,
            };
            let rgb = relight::relight(&compute, &ptm, &light)?;
            relight::to_image(ptm.width, ptm.height, &rgb)
        }
        None => {
            let lights = relight::ring(a.sweep.unwrap() as usize, elevation, a.specular);
            let bar = super::progress_bar(quiet || a.json);
            bar.set_message("relighting");
            let sheet = relight::contact_sheet(&compute, &ptm, &lights, &mut |done, total| {
                bar.set_length(total as u64);
                bar.set_position(done as u64);
            })?;
            bar.finish_and_clear();
            sheet
        }
    };
    atomic::save_png(&a.output, &img)?;
    if a.json {
        print_summary(&RelightSummary {
            output: &a.output,
            width: img.width(),
            height: img.height(),
            lights: a.sweep.unwrap_or(1),
            seconds: start.elapsed().as_secs_f64(),
            backend: compute.describe(),
        });
    } else if !quiet {
        eprintln!(
            "relit a {}x{} PTM in {:.3} s ({}) -> {}",
            ptm.width,
            ptm.height,
            start.elapsed().as_secs_f64(),
            compute.describe(),
            a.output.display()
        );
    }
    Ok(())
}

pub fn run(cmd: PtmCommand, quiet: bool) -> anyhow::Result<()> {
    match cmd {
        PtmCommand::Capture(a) => capture_cmd(a, quiet),
        PtmCommand::Fit(a) => fit_cmd(a, quiet),
        PtmCommand::Synth(a) => synth_cmd(a, quiet),
        PtmCommand::Relight(a) => relight_cmd(a, quiet),
    }
}

/// `ptm capture --json`.
#[derive(serde::Serialize)]
struct CaptureSummary<'a> {
    output: &'a std::path::Path,
    images: u32,
    size: u32,
    seed: u64,
    seconds: f64,
}

/// `ptm fit --json`.
#[derive(serde::Serialize)]
struct FitSummary<'a> {
    output: &'a std::path::Path,
    images: usize,
    width: u32,
    height: u32,
    format: &'static str,
    rms_error_levels: f64,
    seconds: f64,
}

/// `ptm synth --json`.
#[derive(serde::Serialize)]
struct QuiltSummary<'a> {
    output: &'a std::path::Path,
    size: u32,
    blocks: [u32; 2],
    seconds: f64,
    /// As `--search` names it.
    search: &'a str,
    surviving_fraction_per_stage: Vec<f64>,
    exact_distances_per_query: f64,
}

/// `ptm relight --json`.
#[derive(serde::Serialize)]
struct RelightSummary<'a> {
    output: &'a std::path::Path,
    width: u32,
    height: u32,
    lights: u32,
    seconds: f64,
    backend: String,
}
