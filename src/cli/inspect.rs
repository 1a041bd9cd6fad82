//! `solidsynth inspect`.

use crate::analysis::{candidate_stats, slab};
use crate::io::{atomic, ssa};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
#[command(next_help_heading = "Output")]
pub struct InspectArgs {
    /// The .ssa file.
    pub file: PathBuf,
    /// Where to write the candidate slab sheet (default: FILE with extension .slab.png).
    #[arg(long)]
    pub slab: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: InspectArgs) -> anyhow::Result<()> {
    let a = ssa::load(&args.file)?;
    let slab_path = args
        .slab
        .clone()
        .unwrap_or_else(|| args.file.with_extension("slab.png"));
    atomic::check_png_output(&slab_path, "--slab")?;
    let axes = if a.shared { 1 } else { 3 };
    let mut levels_json = Vec::new();
    let mut table = String::new();
    table.push_str(&format!(
        "{}: {} colour channel(s){}, {} border, {}\n",
        args.file.display(),
        a.color_channels,
        if a.has_feature {
            " + feature distance"
        } else {
            ""
        },
        match a.border {
            crate::exemplar::Border::Wrap => "periodic",
            crate::exemplar::Border::Mirror => "mirrored",
        },
        if a.shared {
            "one exemplar shared by x, y, z"
        } else {
            "three exemplars"
        },
    ));
    table.push_str("level  size       exemplar  PCA dims  energy  3D cand. mean  min  max  none   best CB  rounds  penalized  max pen.\n");
    for level in 0..a.level_count() {
        for ax in 0..axes {
            let l = &a.exemplar(ax).levels[level];
            let s = candidate_stats(&a, ax, level);
            let penalized =
                l.penalty.iter().filter(|&&p| p > 0).count() as f64 / l.penalty.len().max(1) as f64;
            let max_penalty = l.penalty.iter().copied().max().unwrap_or(0);
            table.push_str(&format!(
                "{:<6} {:<10} {:<9} {:>8}  {:>5.1}%  {:>13.2}  {:>3}  {:>3}  {:>4}  {:>8.0}  {:>6}  {:>8.1}%  {:>8}\n",
                level,
                format!("{}x{}", l.image.width, l.image.height),
                ["x", "y", "z"][ax],
                l.pca.output_dims,
                100.0 * l.pca.energy_kept(),
                s.mean,
                s.min,
                s.max,
                s.pixels_without,
                l.stats.mean_best_cb,
                l.stats.filter_rounds,
                100.0 * penalized,
                max_penalty,
            ));
            let axis = ["x", "y", "z"][ax];
            levels_json.push(LevelSummary {
                level,
                exemplar: axis,
                width: l.image.width,
                height: l.image.height,
                pca_dims: l.pca.output_dims,
                pca_energy_kept: l.pca.energy_kept(),
                candidates_3d: s,
                k2d: a.params.k2d[level],
                mean_best_crossbar_error: l.stats.mean_best_cb,
                filter_rounds: l.stats.filter_rounds,
                penalized_fraction: penalized,
                max_penalty_sixteenths: max_penalty,
            });
        }
    }
    atomic::save_png(&slab_path, &slab::slab_sheet(&a, 0))?;
    if args.json {
        super::output::print_summary(&InspectSummary {
            file: &args.file,
            shared: a.shared,
            color_channels: a.color_channels,
            feature_channel: a.has_feature,
            levels: levels_json,
            slab_png: &slab_path,
        });
    } else {
        print!("{table}");
        println!(
            "level 0 is the finest; 'none' = pixels left without 3D candidates (cf. paper Fig. 13)"
        );
        println!(
            "usage balancing: {} rounds, strength {}; 'penalized' = pixels the correction \
             over-used in calibration, 'max pen.' in sixteenths of a distance",
            a.params.balance_rounds, a.params.balance_strength
        );
        println!(
            "candidate slab of Ex (rows: levels, columns: depth -2..2) -> {}",
            slab_path.display()
        );
    }
    Ok(())
}

/// `inspect --json`.
#[derive(serde::Serialize)]
struct InspectSummary<'a> {
    file: &'a std::path::Path,
    shared: bool,
    color_channels: u32,
    feature_channel: bool,
    levels: Vec<LevelSummary>,
    slab_png: &'a std::path::Path,
}

/// One exemplar's level in `inspect --json`.
#[derive(serde::Serialize)]
struct LevelSummary {
    level: usize,
    exemplar: &'static str,
    width: u32,
    height: u32,
    pca_dims: u32,
    pca_energy_kept: f64,
    candidates_3d: crate::analysis::CandidateStats,
    k2d: u32,
    mean_best_crossbar_error: f64,
    filter_rounds: u32,
    penalized_fraction: f64,
    max_penalty_sixteenths: u8,
}
