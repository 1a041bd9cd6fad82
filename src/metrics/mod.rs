//! Objective quality of a solid texture against its exemplar(s): slices in every direction should
//! look like new pieces of the exemplar. See [`evaluate`].

pub mod measures;
pub mod multiscale;
pub mod patches;
pub mod sheet;
pub mod slices;

use crate::error::{Error, Result};
use crate::exemplar::Image;
use crate::volume::Volume;
use serde::Serialize;

/// Side of the square patches compared by coherence and completeness.
pub const PATCH: u32 = 7;

/// Evaluation settings.
#[derive(Clone, Debug)]
pub struct EvalParams {
    /// Slices scored per axis (evenly spaced, away from the faces).
    pub slices_per_axis: u32,
    /// Patches sampled per slice for coherence.
    pub coherence_samples: u32,
    /// Exemplar patches sampled (per axis) for completeness.
    pub completeness_samples: u32,
    /// Cap on exemplar patches searched by coherence (larger exemplars are subsampled on a
    /// regular grid).
    pub max_reference_patches: u32,
    /// Cap on slice patches searched by completeness (likewise).
    pub max_slice_patches: u32,
    pub seed: u64,
}

impl Default for EvalParams {
    fn default() -> Self {
        EvalParams {
            slices_per_axis: 3,
            coherence_samples: 200,
            completeness_samples: 200,
            max_reference_patches: 40_000,
            max_slice_patches: 200_000,
            seed: 1,
        }
    }
}

/// The distances (lower is better).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Scores {
    /// Earth mover's distance between per-channel value histograms, in 0..1 (fraction of 255).
    pub histogram: f64,
    /// RMS difference (0..255 units) from sampled slice patches to their nearest exemplar patch.
    pub coherence: f64,
    /// RMS difference from sampled exemplar patches to their nearest slice patch.
    pub completeness: f64,
    /// Total-variation distance (0..1) between magnitude-weighted gradient-orientation histograms.
    pub orientation: f64,
    /// |ln| of the ratio of mean gradient magnitudes: noise (too sharp) and blur (too soft).
    pub sharpness: f64,
}

impl Scores {
    fn worst(a: &Scores, b: &Scores) -> Scores {
        Scores {
            histogram: a.histogram.max(b.histogram),
            coherence: a.coherence.max(b.coherence),
            completeness: a.completeness.max(b.completeness),
            orientation: a.orientation.max(b.orientation),
            sharpness: a.sharpness.max(b.sharpness),
        }
    }
    /// Each score divided by its floor (floors clamped away from zero).
    pub fn ratio_to(&self, floor: &Scores) -> Scores {
        let r = |v: f64, f: f64, eps: f64| v / f.max(eps);
        Scores {
            histogram: r(self.histogram, floor.histogram, 0.02),
            coherence: r(self.coherence, floor.coherence, 1.0),
            completeness: r(self.completeness, floor.completeness, 1.0),
            orientation: r(self.orientation, floor.orientation, 0.01),
            sharpness: r(self.sharpness, floor.sharpness, 0.05),
        }
    }
    pub fn max_component(&self) -> f64 {
        self.histogram
            .max(self.coherence)
            .max(self.completeness)
            .max(self.orientation)
            .max(self.sharpness)
    }
}

/// The result of an evaluation.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Scores of slices perpendicular to x, y and z.
    pub per_axis: [Scores; 3],
    /// The worst of the three axes, per measure.
    pub worst_axis: Scores,
    /// What texture of the same kind scores: one half of the exemplar against the other.
    pub floor: Scores,
    /// worst_axis / floor.
    pub worst_ratio: Scores,
    /// per_axis / floor.
    pub per_axis_ratio: [Scores; 3],
    /// The multi-scale measures, laid out as the others.
    pub multiscale: MultiScaleReport,
    pub slices_per_axis: u32,
}

/// The multi-scale measures ([`multiscale::MultiScale`]) per axis, worst, floor and ratios.
#[derive(Clone, Debug, Serialize)]
pub struct MultiScaleReport {
    pub per_axis: [multiscale::MultiScale; 3],
    pub worst_axis: multiscale::MultiScale,
    pub floor: multiscale::MultiScale,
    pub worst_ratio: multiscale::MultiScale,
    pub per_axis_ratio: [multiscale::MultiScale; 3],
}

/// The exemplars as a caller gave them (one image, or the X, Y and Z images in `frame`; None:
/// the frame `synth` resolves for them by default) turned to the orientation [`evaluate`] and
/// the contact sheet compare slices against.
pub fn exemplars_in_eval_frame(
    exemplars: Vec<Image>,
    frame: Option<crate::analysis::frame::InputFrame>,
) -> Result<Vec<Image>> {
    use crate::analysis::frame::{resolve_frame, to_crate_frame};
    let frame = resolve_frame(&exemplars, frame)?;
    Ok(to_crate_frame(exemplars, frame))
}

/// Score `volume` against one exemplar (all axes) or three (`exemplars[a]` for slices
/// perpendicular to axis a, in the frame orientation of `analysis::frame`).
pub fn evaluate(volume: &Volume, exemplars: &[Image], params: &EvalParams) -> Result<Report> {
    if !matches!(exemplars.len(), 1 | 3) {
        return Err(Error::invalid(
            "exemplars",
            format!(
                "{} images: give one (all axes) or three (x, y, z)",
                exemplars.len()
            ),
        ));
    }
    volume.check("volume")?;
    let min_side = volume.nx.min(volume.ny).min(volume.nz);
    if min_side < PATCH + 2 {
        return Err(Error::invalid(
            "volume",
            format!(
                "is {}x{}x{}; each side must be at least {} voxels",
                volume.nx,
                volume.ny,
                volume.nz,
                PATCH + 2
            ),
        ));
    }
    // Slices are spread evenly, one voxel apart at the closest: more than the sides hold would
    // score some slices twice.
    let most = min_side - 1;
    if params.slices_per_axis == 0 || params.slices_per_axis > most {
        return Err(Error::invalid(
            format!("--slices {}", params.slices_per_axis),
            format!(
                "must be 1..={most}: the volume is {}x{}x{}, and each slice must be a different \
                 plane",
                volume.nx, volume.ny, volume.nz
            ),
        ));
    }
    // Named "exemplar", or with three "exemplar x", "exemplar y", "exemplar z".
    let name = |i: usize| match exemplars.len() {
        1 => "exemplar".to_string(),
        _ => format!("exemplar {}", ["x", "y", "z"][i]),
    };
    for (i, e) in exemplars.iter().enumerate() {
        e.check(&name(i))?;
    }
    let ex: Vec<Image> = exemplars
        .iter()
        .map(|e| e.with_channels(volume.channels))
        .collect();
    for (i, e) in ex.iter().enumerate() {
        if e.width < 2 * PATCH || e.height < 2 * PATCH {
            return Err(Error::invalid(
                name(i),
                format!(
                    "is {}x{}; each side must be at least {}",
                    e.width,
                    e.height,
                    2 * PATCH
                ),
            ));
        }
    }
    let exemplar_for = |a: usize| &ex[if ex.len() == 3 { a } else { 0 }];
    let mut per_axis = [Scores::default(); 3];
    let mut multi = [multiscale::MultiScale::default(); 3];
    let mut floors = Vec::new();
    let mut multi_floors = Vec::new();
    for a in 0..3 {
        let reference = exemplar_for(a);
        let slices = slices::axis_slices(volume, a, params.slices_per_axis);
        per_axis[a] = score_images(&slices, reference, params, a as u64);
        multi[a] = multiscale::score(&slices, reference);
        if a == 0 || ex.len() == 3 {
            let (left, right) = slices::halves(reference);
            floors.push(score_images(
                std::slice::from_ref(&right),
                &left,
                params,
                100 + a as u64,
            ));
            multi_floors.push(multiscale::score(&[right], &left));
        }
    }
    let multi_floor = multi_floors.iter().skip(1).fold(multi_floors[0], |acc, f| {
        multiscale::MultiScale::worst(&acc, f)
    });
    let multi_worst = multiscale::MultiScale::worst(
        &multiscale::MultiScale::worst(&multi[0], &multi[1]),
        &multi[2],
    );
    let multiscale = MultiScaleReport {
        per_axis: multi,
        worst_axis: multi_worst,
        floor: multi_floor,
        worst_ratio: multi_worst.ratio_to(&multi_floor),
        per_axis_ratio: multi.map(|m| m.ratio_to(&multi_floor)),
    };
    let floor = floors
        .iter()
        .skip(1)
        .fold(floors[0], |acc, f| Scores::worst(&acc, f));
    let worst_axis = Scores::worst(&Scores::worst(&per_axis[0], &per_axis[1]), &per_axis[2]);
    Ok(Report {
        per_axis,
        worst_axis,
        floor,
        worst_ratio: worst_axis.ratio_to(&floor),
        per_axis_ratio: per_axis.map(|s| s.ratio_to(&floor)),
        multiscale,
        slices_per_axis: params.slices_per_axis,
    })
}

/// The measures of a set of images against one reference image.
pub fn score_images(
    images: &[Image],
    reference: &Image,
    params: &EvalParams,
    stream: u64,
) -> Scores {
    let seed = params.seed ^ (stream << 32);
    Scores {
        histogram: measures::histogram_distance(images, reference),
        coherence: patches::coherence(
            images,
            reference,
            params.coherence_samples,
            params.max_reference_patches,
            seed,
        ),
        completeness: patches::completeness(
            images,
            reference,
            params.completeness_samples,
            params.max_slice_patches,
            seed ^ 0xC0,
        ),
        orientation: measures::orientation_distance(images, reference),
        sharpness: measures::sharpness_distance(images, reference),
    }
}
