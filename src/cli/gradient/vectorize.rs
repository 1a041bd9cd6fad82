//! `gradient vectorize`: a volume fitted with a gradient solid, plain or region-separated.

use super::VectorizeArgs;
use crate::backend::Compute;
use crate::cli::output::print_summary;
use crate::gradient::regions::{self, Blend, RegionSolid};
use crate::gradient::{detail, format, vectorize};
use crate::io::{atomic, nrrd};
use crate::Error;
use std::path::Path;
use std::time::Instant;

/// `gradient vectorize`: fit, store, and report the stored file's error.
pub(super) fn vectorize(a: VectorizeArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&a.output, "-o")?;
    atomic::check_output_extension(&a.output, "-o", "a gradient solid", &["gsolid"])?;
    let volume = nrrd::load(&a.input)?;
    if let Some(mask) = &a.mask {
        if a.detail {
            return Err(Error::invalid(
                "--detail",
                "is not available with --mask (region solids have no detail channels)",
            )
            .into());
        }
        return vectorize_with_mask(&a, &volume, mask, quiet);
    }
    let start = Instant::now();
    let mut solid = vectorize::vectorize(&volume)?;
    if a.optimize {
        vectorize::optimize(&mut solid, &volume, a.iterations as usize);
    }
    if a.detail {
        solid = detail::with_detail(&solid, &volume)?;
    }
    let fit_s = start.elapsed().as_secs_f64();
    let bytes = format::to_bytes(&solid, a.encoding);
    // The error of what is stored: decode the file's own bytes and render them.
    let stored = format::from_bytes(&bytes, "encoded solid")?;
    let rendered = vectorize::render(&stored, [volume.nx, volume.ny, volume.nz]);
    let rms = vectorize::rms(&rendered, &volume);
    let fraction = bytes.len() as f64 / volume.data.len() as f64;
    atomic::write_file(&a.output, &bytes)?;
    if a.json {
        print_summary(&VectorizeSummary {
            output: &a.output,
            grid: solid.dims,
            split_points: None,
            rms,
            rms_antialiased: None,
            rms_without_regions: None,
            seconds: fit_s,
            bytes: bytes.len(),
            fraction_of_volume: fraction,
        });
    } else if !quiet {
        eprintln!(
            "vectorized {}x{}x{} into a {:?} control grid in {fit_s:.2} s: RMS error {rms:.2}, \
             {} bytes ({:.1}% of the volume) -> {}",
            volume.nx,
            volume.ny,
            volume.nz,
            solid.dims,
            bytes.len(),
            fraction * 100.0,
            a.output.display()
        );
    }
    Ok(())
}

/// `gradient vectorize --mask`: region separation; reports the stored file's error with and
/// without the anti-aliasing blend, and the plain fit's for comparison.
fn vectorize_with_mask(
    a: &VectorizeArgs,
    volume: &crate::volume::Volume,
    mask_path: &Path,
    quiet: bool,
) -> anyhow::Result<()> {
    let mask = nrrd::load(mask_path)?;
    let start = Instant::now();
    let mut rs = regions::vectorize_regions(volume, &mask, &mask_path.display().to_string())?;
    if a.optimize {
        rs.optimize(volume, a.iterations as usize);
    }
    let fit_s = start.elapsed().as_secs_f64();
    let bytes = rs.to_bytes(a.encoding);
    let stored = RegionSolid::from_bytes(&bytes, "encoded solid")?;
    let n = volume.dims();
    let exact = vectorize::rms(&stored.render(n, &Compute::Cpu, Blend::Exact)?, volume);
    let aa = vectorize::rms(
        &stored.render(n, &Compute::Cpu, Blend::Antialiased)?,
        volume,
    );
    // The comparison: the plain fit with the same refinement.
    let mut plain_fit = vectorize::vectorize(volume)?;
    if a.optimize {
        vectorize::optimize(&mut plain_fit, volume, a.iterations as usize);
    }
    let plain_solid = format::from_bytes(&format::to_bytes(&plain_fit, a.encoding), "plain solid")?;
    let plain = vectorize::rms(&vectorize::render(&plain_solid, n), volume);
    let fraction = bytes.len() as f64 / volume.data.len() as f64;
    atomic::write_file(&a.output, &bytes)?;
    if a.json {
        print_summary(&VectorizeSummary {
            output: &a.output,
            grid: rs.positive.dims,
            split_points: Some(rs.split_points()),
            rms: exact,
            rms_antialiased: Some(aa),
            rms_without_regions: Some(plain),
            seconds: fit_s,
            bytes: bytes.len(),
            fraction_of_volume: fraction,
        });
    } else if !quiet {
        eprintln!(
            "vectorized {}x{}x{} with regions into a {:?} control grid ({} split points) in \
             {fit_s:.2} s: RMS error {exact:.2} ({aa:.2} anti-aliased; {plain:.2} without \
             regions), {} bytes ({:.1}% of the volume) -> {}",
            n[0],
            n[1],
            n[2],
            rs.positive.dims,
            rs.split_points(),
            bytes.len(),
            fraction * 100.0,
            a.output.display()
        );
    }
    Ok(())
}

/// `gradient vectorize --json` (the region fields with `--mask` only).
#[derive(serde::Serialize)]
struct VectorizeSummary<'a> {
    output: &'a Path,
    grid: [u32; 3],
    #[serde(skip_serializing_if = "Option::is_none")]
    split_points: Option<usize>,
    rms: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_antialiased: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_without_regions: Option<f64>,
    seconds: f64,
    bytes: usize,
    fraction_of_volume: f64,
}
