//! `gradient edit`: a .gsolid recoloured by strokes (instant editing).

use super::{load, EditArgs};
use crate::cli::output::print_summary;
use crate::gradient::{edit, format};
use crate::io::atomic;
use crate::Error;
use std::path::Path;
use std::time::Instant;

/// `gradient edit`: apply the strokes' recolouring and write the edited solid.
pub(super) fn edit(a: EditArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&a.output, "-o")?;
    atomic::check_output_extension(&a.output, "-o", "a gradient solid", &["gsolid"])?;
    let mut solid = load(&a.input)?;
    if solid.detail > 0 {
        return Err(Error::invalid(
            a.input.display().to_string(),
            "has detail channels; editing takes solids without them (vectorize without \
             --detail)",
        )
        .into());
    }
    let text = crate::io::input::read_text(&a.strokes)?;
    let strokes = edit::parse_strokes(&text, &a.strokes.display().to_string())?;
    let reference: Vec<f64> = a
        .color
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.iter().all(|x| (0.0..=255.0).contains(x)))
        .ok_or_else(|| {
            Error::invalid(
                format!("--color {}", a.color),
                "expected numbers in 0..=255 like 255,0,0",
            )
        })?;
    let start = Instant::now();
    let propagation = edit::Propagation {
        alpha: a.alpha,
        beta: a.beta,
    };
    let before = solid.data.clone();
    let residual = edit::edit(&mut solid, &strokes, &reference, propagation)?;
    let seconds = start.elapsed().as_secs_f64();
    let values = solid.channels as usize * 4;
    let changed = (solid.data.chunks_exact(values))
        .zip(before.chunks_exact(values))
        .filter(|(after, before)| after != before)
        .count();
    if changed == 0 {
        // Nothing would be written but a copy: strokes far from the solid, or of strength 0.
        let [x, y, z] = solid.extent().map(|e| e - 1);
        return Err(Error::invalid(
            a.strokes.display().to_string(),
            format!(
                "the strokes change no control point: their positions must reach the solid \
                 (voxels 0..={x}, 0..={y}, 0..={z}) with a strength above 0"
            ),
        )
        .into());
    }
    // The file must read back: a reference colour far outside the solid's values can push
    // them past what the encoding holds (a u8 step that overflows to infinity).
    let bytes = format::to_bytes(&solid, a.encoding);
    if let Err(e) = format::from_bytes(&bytes, "edited solid") {
        return Err(Error::invalid(
            format!("--color {}", a.color),
            format!(
                "moves the solid's values where the {} encoding cannot store them ({e}); \
                 choose a colour nearer the solid's own",
                format!("{:?}", a.encoding).to_lowercase()
            ),
        )
        .into());
    }
    atomic::write_file(&a.output, &bytes)?;
    if a.json {
        print_summary(&EditSummary {
            output: &a.output,
            strokes: strokes.len(),
            seconds,
            strength_fit_rms: residual,
            control_points: solid.data.len() / values,
            changed_points: changed,
        });
    } else if !quiet {
        eprintln!(
            "changed {changed} of {} control points with {} strokes in {seconds:.3} s \
             (strength fit RMS {residual:.3}) -> {}",
            solid.data.len() / values,
            strokes.len(),
            a.output.display()
        );
    }
    Ok(())
}

/// `gradient edit --json`.
#[derive(serde::Serialize)]
struct EditSummary<'a> {
    output: &'a Path,
    strokes: usize,
    seconds: f64,
    strength_fit_rms: f64,
    control_points: usize,
    /// Control points whose values the strokes changed.
    changed_points: usize,
}
