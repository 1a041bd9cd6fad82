//! Final region separation of a synthesis with a mask (paper 4.3, "Region separation"; the
//! representation of 3.2).
//!
//! The iterations synthesize the mask's signed distance as one more feature channel (4.2.4:
//! intermediate synthesis ignores the regions). After the last iteration every voxel's bucket
//! average (its samples of one region only, see `buckets`) is a dense sample of colour and
//! distance; the voxels whose distance lies on the positive side of the encoded zero (128) form
//! a binary mask volume, and [`vectorize_regions`] turns colours + mask into a [`RegionSolid`]:
//! the distance field of the mask, and f^P / f^N fitted at the split points from the samples of
//! each sign only (the paper's per-sign fits). Voxels without a sample take the synthesized
//! solid's own value.
//!
//! Periodicity: `vectorize_regions` works on a bounded volume (clipped neighbourhoods at its
//! faces), so it runs on the periodic samples extended by [`PAD`] wrapped voxels on every side;
//! the control points of one period are cut out of the result, and the last face of every grid
//! is set to its first (point m = point 0, as in [`PeriodicSolid::to_gradient_solid`]): the
//! region solid tiles with period P. Every fit of a point of the period then sees the same
//! wrapped neighbourhood as on an infinite tiling; only the distance values deeper than the
//! margin inside a region (where only the sign matters) may differ from a periodic transform.
//! With eq. 3 (`RegionSolid::optimize`), the refinement runs on the padded volume, so the cut-out
//! points are fitted with wrapped neighbours too; copying the first face onto the last then
//! replaces the last face's refined values by the first face's (equal up to the margin's edge
//! effects on the global solve): the stored solid tiles exactly either way.
//!
//! Memory: the dense samples (4 f32 per voxel) plus the padded colour and mask volumes and the
//! vectorizer's distance transforms (a few f32 per padded voxel; eq. 3 adds its stencils): sizes
//! up to [`super::MAX_OPTIMIZE_SIZE`].

use super::refine::Targets;
use super::PeriodicSolid;
use crate::backend::host_tricubic_eval as tricubic_eval;
use crate::contract::tricubic::Query;
use crate::error::{Error, Result};
use crate::gradient::regions::{vectorize_regions, RegionSolid};
use crate::gradient::{GradientSolid, SPACING};
use crate::volume::Volume;
use rayon::prelude::*;

/// Wrapped voxels around the period on each side (two control cells): covers the eq. 2
/// neighbourhood (d voxels), the mixed-cube test and the distance's central differences.
pub const PAD: u32 = 2 * SPACING;

/// What the separation did.
#[derive(Clone, Debug, Default)]
pub struct Separation {
    /// Fraction of voxels whose bucket got no sample (filled from the solid).
    pub empty: f64,
    /// RMS error of eq. 3 over the padded samples, before and after (with `optimize`).
    pub optimize_rms: Option<(f64, f64)>,
}

/// The region solid of a periodic synthesis from its last samples: `targets` has the colour
/// channels first and the encoded signed distance last. `optimize`: CG steps of eq. 3 (0: off).
pub fn separate(
    solid: &PeriodicSolid,
    targets: &Targets,
    optimize: usize,
) -> Result<(RegionSolid, Separation)> {
    let ch = targets.channels;
    let colours = ch - 1;
    let p = targets.period as u32;
    let n = p + 2 * PAD + 1;
    let plain = solid.to_gradient_solid()?;
    let mut rgb = Volume::new(n, n, n, colours as u32);
    let mut mask = Volume::new(n, n, n, 1);
    let row = n as usize;
    rgb.data
        .par_chunks_mut(row * colours)
        .zip(mask.data.par_chunks_mut(row))
        .enumerate()
        .for_each(|(r, (rgb, mask))| {
            let wrap = |v: usize| (v as i64 - PAD as i64).rem_euclid(p as i64) as usize;
            let (y, z) = (wrap(r % row), wrap(r / row));
            let mut value = vec![0f32; ch];
            for x in 0..row {
                let v = (z * p as usize + y) * p as usize + wrap(x);
                value.copy_from_slice(&targets.values[v * ch..(v + 1) * ch]);
                if value[0].is_nan() {
                    plain.eval([wrap(x) as f32, y as f32, z as f32], &mut value);
                }
                for (o, &f) in rgb[x * colours..(x + 1) * colours].iter_mut().zip(&value) {
                    *o = f.round().clamp(0.0, 255.0) as u8;
                }
                mask[x] = if value[colours] >= 128.0 { 255 } else { 0 };
            }
        });
    let empty = targets
        .values
        .iter()
        .step_by(ch)
        .filter(|v| v.is_nan())
        .count() as f64
        / (p as f64).powi(3);
    let mut padded =
        vectorize_regions(&rgb, &mask, "the synthesized region mask").map_err(|e| match e {
            Error::InvalidInput { problem, .. } => Error::invalid(
                "--mask",
                format!("region separation of the synthesized solid failed: {problem}"),
            ),
            other => other,
        })?;
    let optimize_rms = (optimize > 0).then(|| {
        let before = rms(&padded, &rgb);
        let history = padded.optimize(&rgb, optimize);
        (before, history.last().copied().unwrap_or(before))
    });
    Ok((
        one_period(&padded, p / SPACING)?,
        Separation {
            empty,
            optimize_rms,
        },
    ))
}

/// RMS error (0..255) of the exact evaluation of `rs` against `v`.
fn rms(rs: &RegionSolid, v: &Volume) -> f64 {
    let n = v.dims();
    match rs.render(
        n,
        &crate::backend::Compute::Cpu,
        crate::gradient::regions::Blend::Exact,
    ) {
        Ok(r) => crate::gradient::vectorize::rms(&r, v),
        Err(_) => f64::NAN,
    }
}

/// Points [PAD / d, PAD / d + m] of the padded solid, the last face a copy of the first.
fn one_period(padded: &RegionSolid, m: u32) -> Result<RegionSolid> {
    let off = PAD / SPACING;
    let cut = |s: &GradientSolid| -> Result<GradientSolid> {
        let mut out = GradientSolid::new([m + 1; 3], s.channels)?;
        let per = s.channels as usize * 4;
        for z in 0..=m {
            for y in 0..=m {
                for x in 0..=m {
                    let src = s.point_index([x % m + off, y % m + off, z % m + off]) * per;
                    let dst = out.point_index([x, y, z]) * per;
                    out.data[dst..dst + per].copy_from_slice(&s.data[src..src + per]);
                }
            }
        }
        Ok(out.into_periodic())
    };
    let distance = cut(&padded.distance)?;
    let split = (0..(m as usize + 1).pow(3))
        .map(|i| {
            let q = [i, i / (m as usize + 1), i / (m as usize + 1).pow(2)]
                .map(|v| (v % (m as usize + 1)) as u32 % m + off);
            padded.split[padded.distance.point_index(q)]
        })
        .collect();
    Ok(RegionSolid {
        positive: cut(&padded.positive)?,
        negative: cut(&padded.negative)?,
        distance,
        split,
    })
}

/// Fraction of the voxels of one period [0, P)^3 on the positive side of `rs`'s distance.
pub fn positive_fraction(rs: &RegionSolid) -> f64 {
    let p = rs.extent()[0] - 1;
    let d = tricubic_eval(&rs.distance, &Query::volume([p; 3]));
    d.iter().filter(|&&v| v >= 0.0).count() as f64 / d.len().max(1) as f64
}
