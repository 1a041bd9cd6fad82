//! `solidsynth eval`.

use crate::analysis::frame::InputFrame;
use crate::exemplar;
use crate::io::{atomic, nrrd};
use crate::metrics::multiscale::MultiScale;
use crate::metrics::{self, sheet, EvalParams, Scores};
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
#[command(next_help_heading = "Evaluation")]
pub struct EvalArgs {
    /// The exemplar the volume was made from (for all three axes unless --ey/--ez are given).
    pub exemplar: PathBuf,
    /// The volume: NRRD, uint8, 1/3/4 channels, raw or gzip.
    pub volume: PathBuf,
    /// Exemplar of the slices perpendicular to y.
    #[arg(long, requires = "ez")]
    pub ey: Option<PathBuf>,
    /// Exemplar of the slices perpendicular to z.
    #[arg(long, requires = "ey")]
    pub ez: Option<PathBuf>,
    /// The frame the exemplars were given in when the volume was made (as `synth --frame`,
    /// and the same default: `paper` where it fits, i.e. a square y exemplar, else `cyclic`):
    /// with `paper`, the slices perpendicular to y, cut with columns along z and rows along x,
    /// are scored against the y exemplar transposed.
    #[arg(long, value_enum)]
    pub frame: Option<InputFrame>,
    /// Slices scored per axis.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub slices: u32,
    /// Seed of the patch sampling (the evaluation is deterministic for a given seed).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print JSON instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
    /// Write a contact sheet (exemplar beside orthogonal slices) to this PNG.
    #[arg(help_heading = "Output", long)]
    pub sheet: Option<PathBuf>,
}

pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    if let Some(s) = &args.sheet {
        atomic::check_png_output(s, "--sheet")?;
    }
    let start = Instant::now();
    let mut exemplars = vec![exemplar::load_image(&args.exemplar, "exemplar")?];
    if let (Some(ey), Some(ez)) = (&args.ey, &args.ez) {
        exemplars.push(exemplar::load_image(ey, "--ey")?);
        exemplars.push(exemplar::load_image(ez, "--ez")?);
    }
    let exemplars = metrics::exemplars_in_eval_frame(exemplars, args.frame)?;
    let volume = nrrd::load(&args.volume)?;
    let params = EvalParams {
        slices_per_axis: args.slices,
        seed: args.seed,
        ..Default::default()
    };
    // The library names the volume and the exemplars by role; the command by their files.
    // (One image stands for all three planes unless --ey and --ez are given.)
    let file = |what: &str| -> Option<String> {
        let (flag, path) = match (what, &args.ey, &args.ez) {
            ("volume", ..) => ("volume", &args.volume),
            ("exemplar y", Some(ey), _) => ("--ey", ey),
            ("exemplar z", _, Some(ez)) => ("--ez", ez),
            ("exemplar" | "exemplar x" | "exemplar y" | "exemplar z", ..) => {
                ("exemplar", &args.exemplar)
            }
            _ => return None,
        };
        Some(format!("{flag} {}", path.display()))
    };
    let report = metrics::evaluate(&volume, &exemplars, &params).map_err(|e| match e {
        crate::Error::InvalidInput { what, problem } => match file(&what) {
            Some(named) => crate::Error::invalid(named, problem),
            None => crate::Error::InvalidInput { what, problem },
        },
        other => other,
    })?;
    if let Some(path) = &args.sheet {
        atomic::save_png(path, &sheet::contact_sheet(&volume, &exemplars))?;
    }
    if args.json {
        let mut report = serde_json::to_value(&report)?;
        report["schema"] = 1.into();
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{} vs {} ({}x{}x{}, {} slices per axis, {:.2} s)",
        args.volume.display(),
        args.exemplar.display(),
        volume.nx,
        volume.ny,
        volume.nz,
        args.slices,
        start.elapsed().as_secs_f64()
    );
    println!(
        "{:<13} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
        "measure", "x", "y", "z", "worst", "floor", "ratio"
    );
    let rows: [(&str, fn(&Scores) -> f64); 5] = [
        ("histogram", |s| s.histogram),
        ("coherence", |s| s.coherence),
        ("completeness", |s| s.completeness),
        ("orientation", |s| s.orientation),
        ("sharpness", |s| s.sharpness),
    ];
    for (name, get) in rows {
        println!(
            "{:<13} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>8.2}",
            name,
            get(&report.per_axis[0]),
            get(&report.per_axis[1]),
            get(&report.per_axis[2]),
            get(&report.worst_axis),
            get(&report.floor),
            get(&report.worst_ratio)
        );
    }
    let m = &report.multiscale;
    let multi_rows: [(&str, fn(&MultiScale) -> f64); 4] = [
        ("swd full", |s| s.swd[0]),
        ("swd 1/2", |s| s.swd[1]),
        ("swd 1/4", |s| s.swd[2]),
        ("spectrum", |s| s.spectrum),
    ];
    // A scale whose images hold no 5x5 patch has no distance (NaN; null in --json).
    let cell = |v: f64, precision: usize| match v.is_nan() {
        true => format!("{:>8}", "n/a"),
        false => format!("{v:>8.precision$}"),
    };
    let mut unscored = false;
    for (name, get) in multi_rows {
        let values = [
            get(&m.per_axis[0]),
            get(&m.per_axis[1]),
            get(&m.per_axis[2]),
            get(&m.worst_axis),
            get(&m.floor),
        ];
        unscored |= values.iter().any(|v| v.is_nan());
        let cells: Vec<String> = values.iter().map(|&v| cell(v, 3)).collect();
        println!(
            "{:<13} {} {}",
            name,
            cells.join(" "),
            cell(get(&m.worst_ratio), 2)
        );
    }
    println!("lower is better; floor = one half of the exemplar scored against the other; ratio = worst / floor");
    println!("swd: sliced Wasserstein distance of mean-removed 5x5 patches at full, half and quarter resolution; spectrum: radially averaged log power spectrum");
    if unscored {
        println!("n/a: the slices or the exemplar's halves are too small for 5x5 patches at that resolution (a quarter needs at least 20 pixels a side)");
    }
    Ok(())
}
