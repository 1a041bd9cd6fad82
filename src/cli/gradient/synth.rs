//! `gradient synth`: a gradient solid synthesized directly from a 2D exemplar.

use super::{SearchArg, SynthArgs};
use crate::cli::output::print_summary;
use crate::gradient::format;
use crate::io::atomic;
use crate::Error;
use std::path::Path;

/// `gradient synth`: synthesize, optionally optimize, write the .gsolid and report per level.
pub(super) fn synth(a: SynthArgs, quiet: bool) -> anyhow::Result<()> {
    use crate::gradient::synth::{self, Field, GradientSynthParams, SliceSearch};
    atomic::check_output_path(&a.output, "-o")?;
    atomic::check_output_extension(&a.output, "-o", "a gradient solid", &["gsolid"])?;
    let exemplar = match &a.input {
        Some(path) => crate::exemplar::load_image(path, "exemplar")?,
        None => crate::exemplar::default_exemplar(),
    };
    let name = a
        .input
        .as_ref()
        .map_or("built-in exemplar".to_string(), |p| p.display().to_string());
    crate::exemplar::check_exemplar_size(&exemplar, &name)?;
    let field = Field::parse(&a.field).ok_or_else(|| {
        Error::invalid(
            format!("--field {}", a.field),
            "expected none, constant:X,Y,Z or cylinder:X,Y,Z with a non-zero direction",
        )
    })?;
    let params = GradientSynthParams {
        seed: a.seed,
        size: a.size,
        iterations: a.iterations,
        check_points: a.check_points,
        clusters: a.clusters,
        search: match a.search {
            SearchArg::Crossbar => SliceSearch::Crossbar { n1: 20, n2: 50 },
            SearchArg::CrossbarNearest => SliceSearch::CrossbarNearest { n1: 20, n2: 50 },
            SearchArg::Independent => SliceSearch::Independent,
        },
        field,
        matched_slices: a.slices,
        optimize_iterations: if a.optimize { a.optimize_iterations } else { 0 },
        probes: (a.probes > 0).then_some(a.probes),
        ..Default::default()
    };
    params.validate()?;
    let side = params.min_exemplar_side();
    if exemplar.width < side || exemplar.height < side {
        return Err(Error::invalid(
            name,
            format!(
                "is {}x{}; gradient synthesis needs at least {side}x{side} pixels (its coarsest \
                 patches span that much)",
                exemplar.width, exemplar.height
            ),
        )
        .into());
    }
    let masked = match &a.mask {
        Some(path) => {
            params.validate_with_mask()?;
            let what = format!("--mask {}", path.display());
            let bytes = crate::io::input::read(path).map_err(|e| match e {
                Error::Io { source, .. } => Error::invalid(
                    &what,
                    format!(
                        "cannot read the file: {}",
                        crate::error::io_problem(&source)
                    ),
                ),
                other => other,
            })?;
            let mask = crate::exemplar::decode_image(&bytes, &what)?;
            Some(synth::MaskedExemplar::new(&exemplar, &mask, &what)?)
        }
        None => None,
    };
    let compute = a.backend.open()?;
    let bar = crate::cli::progress_bar(quiet || a.json);
    bar.set_length(1000);
    let progress = |msg: &str, f: f32| {
        bar.report(msg, f);
    };
    let (bytes, grid, report) = match &masked {
        Some(m) => {
            let (rs, report) = synth::synthesize_regions(m, &params, &compute, &progress)?;
            (rs.to_bytes(a.encoding), rs.positive.dims, report)
        }
        None => {
            let (solid, report) = synth::synthesize(&exemplar, &params, &compute, &progress)?;
            let solid = solid.to_gradient_solid()?;
            (format::to_bytes(&solid, a.encoding), solid.dims, report)
        }
    };
    bar.finish_and_clear();
    atomic::write_file(&a.output, &bytes)?;
    let period = params.cells() * crate::gradient::SPACING;
    // The file against the RGB volume it stands for (a period, 3 bytes per voxel).
    let fraction = bytes.len() as f64 / (3.0 * (period as f64).powi(3));
    if a.json {
        let levels: Vec<_> = report
            .levels
            .iter()
            .map(|l| GradientLevelSummary {
                spacing: l.spec.spacing,
                size: l.spec.size,
                candidates: l.candidates,
                pca_energy: l.pca_energy,
                prepare_seconds: l.prepare_seconds,
                match_seconds: l.match_seconds,
                update_seconds: l.update_seconds,
                refitted: l.refitted,
            })
            .collect();
        print_summary(&GradientSynthSummary {
            output: &a.output,
            grid,
            period,
            seconds: report.seconds,
            bytes: bytes.len(),
            fraction_of_volume: fraction,
            levels,
            optimize_seconds: report.optimize_seconds,
            optimize_rms: [report.optimize_rms.0, report.optimize_rms.1],
            regions: report.regions.as_ref(),
            backend: compute.describe(),
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
        });
    } else if !quiet {
        for l in &report.levels {
            eprintln!(
                "level N={} spacing {}: {} patches (PCA keeps {:.1}%), prepare {:.2} s, match \
                 {:.2} s, update {:.2} s",
                l.spec.size,
                l.spec.spacing,
                l.candidates,
                l.pca_energy * 100.0,
                l.prepare_seconds,
                l.match_seconds,
                l.update_seconds
            );
        }
        if a.optimize {
            eprintln!(
                "final optimization (eq. 3): RMS to the samples {:.2} -> {:.2} in {:.2} s",
                report.optimize_rms.0, report.optimize_rms.1, report.optimize_seconds
            );
        }
        if let Some(r) = &report.regions {
            eprintln!(
                "region separation in {:.2} s: {} of {} control points split, {:.1}% of the \
                 volume positive (exemplar mask: {:.1}%), {:.2}% of the voxels without samples",
                r.seconds,
                r.split_points,
                r.points,
                r.positive_fraction * 100.0,
                r.exemplar_positive_fraction * 100.0,
                r.empty_buckets * 100.0
            );
        }
        eprintln!(
            "synthesized a {}gradient solid of period {period} ({grid:?} control points) in \
             {:.2} s ({}), {} bytes ({:.1}% of the RGB volume) -> {}",
            if masked.is_some() { "region " } else { "" },
            report.seconds,
            compute.describe(),
            bytes.len(),
            fraction * 100.0,
            a.output.display()
        );
    }
    Ok(())
}

/// `gradient synth --json`.
#[derive(serde::Serialize)]
struct GradientSynthSummary<'a> {
    output: &'a Path,
    grid: [u32; 3],
    period: u32,
    seconds: f64,
    bytes: usize,
    fraction_of_volume: f64,
    levels: Vec<GradientLevelSummary>,
    optimize_seconds: f64,
    optimize_rms: [f64; 2],
    regions: Option<&'a crate::gradient::synth::RegionReport>,
    backend: String,
    peak_rss_bytes: Option<u64>,
}

#[derive(serde::Serialize)]
struct GradientLevelSummary {
    spacing: u32,
    size: u32,
    candidates: usize,
    pca_energy: f64,
    prepare_seconds: f64,
    match_seconds: f64,
    update_seconds: f64,
    refitted: f64,
}
