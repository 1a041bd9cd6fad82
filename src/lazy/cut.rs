//! Planar cuts of the solid: an N x N image of the solid sampled on a plane of any orientation.
//!
//! Conventions (so an axis-aligned cut equals the corresponding slice of a box exactly): voxel
//! (x, y, z) is the cell [x, x+1) x [y, y+1) x [z, z+1) and a point samples the voxel containing it;
//! n is the unit normal; v is `up` projected onto the plane and normalized (default +y, or +z when
//! the normal is along y); u = v x n; pixel (column i, row j) samples
//! origin + (i + 0.5 - N/2) s u + (j + 0.5 - N/2) s v, row 0 first.
//!
//! [`CutSession`] keeps a [`Synthesizer`] warm (pipelines, level data) for interactive use. Only
//! the bricks holding sampled voxels are requested ([`Synthesizer::synthesize_bricks`]), so an
//! oblique cut's cost follows its area too (2-3x an axis-aligned one, whose one-voxel-thick box
//! of pixels is planned voxel-exactly; see BENCHMARKS.md).

use super::{ms, Box3, Synthesizer};
use crate::error::{Error, Result};
use crate::exemplar::Image;
use crate::volume::Volume;
use glam::DVec3;
use rayon::prelude::*;

/// The largest distance between a cut's neighbouring pixels, in voxels.
pub const MAX_CUT_SPACING: f64 = 1024.0;

/// A planar cut request.
#[derive(Clone, Debug, PartialEq)]
pub struct CutSpec {
    pub origin: [f64; 3],
    pub normal: [f64; 3],
    pub up: Option<[f64; 3]>,
    /// Pixels per side.
    pub size: u32,
    /// Voxels per pixel.
    pub spacing: f64,
}

/// Largest cut side accepted.
pub const MAX_CUT_SIZE: u32 = 4096;

/// A direction flag's vector, of any length but zero: finite components, not all zero. A vector
/// whose length overflows or is below 1e-9 is scaled by its largest component first (others
/// keep their exact value, so their frames, and cuts, are unchanged).
fn direction(v: [f64; 3], flag: &str) -> Result<DVec3> {
    if !v.iter().all(|c| c.is_finite()) {
        return Err(Error::invalid(flag, "components must be finite numbers"));
    }
    let d = DVec3::from_array(v);
    if d == DVec3::ZERO {
        return Err(Error::invalid(flag, "must not be the zero vector"));
    }
    let length = d.length();
    Ok(if length.is_finite() && length >= 1e-9 {
        d
    } else {
        d / d.abs().max_element()
    })
}

impl CutSpec {
    /// The in-plane axes (u, v) and the normal, validated.
    pub fn frame(&self) -> Result<(DVec3, DVec3, DVec3)> {
        let finite = |v: &[f64; 3]| v.iter().all(|c| c.is_finite());
        if !finite(&self.origin) {
            return Err(Error::invalid(
                "--origin",
                "coordinates must be finite numbers",
            ));
        }
        if !(1..=MAX_CUT_SIZE).contains(&self.size) {
            return Err(Error::invalid(
                format!("--size {}", self.size),
                format!("must be 1..={MAX_CUT_SIZE}"),
            ));
        }
        if !(self.spacing.is_finite() && self.spacing > 0.0 && self.spacing <= MAX_CUT_SPACING) {
            return Err(Error::invalid(
                format!("--spacing {}", crate::util::number_text(self.spacing)),
                format!("must be a number in (0, {MAX_CUT_SPACING}]"),
            ));
        }
        let n = direction(self.normal, "--normal")?.normalize();
        let up = match self.up {
            Some(u) => direction(u, "--up")?,
            None if n.y.abs() > 1.0 - 1e-9 => DVec3::Z,
            None => DVec3::Y,
        };
        let v = up - up.dot(n) * n;
        if v.length() < 1e-9 {
            return Err(Error::invalid("--up", "must not be parallel to the normal"));
        }
        let v = v.normalize();
        Ok((v.cross(n), v, n))
    }

    /// The voxel each pixel samples, row-major.
    pub fn voxels(&self) -> Result<Vec<[i32; 3]>> {
        let frame = self.frame()?;
        let side = self.size as usize;
        let mut out = vec![[0i32; 3]; side * side];
        // Rows in parallel (each pixel's point is computed on its own: the same at any thread
        // count); a warm session's cut is otherwise bound by this loop on a fast GPU.
        let rows_per_piece = (super::PARALLEL_PIECE / side).max(1);
        let inside = out
            .par_chunks_mut(side)
            .with_min_len(rows_per_piece)
            .enumerate()
            .all(|(j, row)| {
                for (i, voxel) in row.iter_mut().enumerate() {
                    match self.voxel_at(frame, i, j) {
                        Some(p) => *voxel = p,
                        None => return false,
                    }
                }
                true
            });
        if !inside {
            return Err(beyond_range());
        }
        Ok(out)
    }

    /// The voxel pixel (column i, row j) samples in `frame` ([`Self::frame`]), or None beyond
    /// +-2^28 voxels. The one definition of a pixel's point, shared by [`Self::voxels`] and
    /// [`AxisCut`] so that both give the same voxels bit for bit.
    fn voxel_at(&self, (u, v, _): (DVec3, DVec3, DVec3), i: usize, j: usize) -> Option<[i32; 3]> {
        let o = DVec3::from_array(self.origin);
        let (n, s) = (self.size as f64, self.spacing);
        let p = o + (i as f64 + 0.5 - n / 2.0) * s * u + (j as f64 + 0.5 - n / 2.0) * s * v;
        let f = p.floor();
        if f.abs().max_element() > super::plan::COORDINATE_LIMIT as f64 {
            return None;
        }
        Some([f.x as i32, f.y as i32, f.z as i32])
    }

    /// This cut as a box of voxels, when it is one: an axis-aligned frame whose columns and
    /// rows step one voxel at a time (spacing 1). None for any other cut.
    fn axis_cut(&self) -> Result<Option<AxisCut>> {
        let frame = self.frame()?;
        let (Some(axis_u), Some(axis_v)) = (unit_axis(frame.0), unit_axis(frame.1)) else {
            return Ok(None);
        };
        let axis_n = 3 - axis_u - axis_v;
        let side = self.size as usize;
        // Along an axis-aligned frame a pixel's coordinate on u's axis depends on its column
        // only (v and the normal add exact zeros there), on v's axis on its row only, and on
        // the normal's axis on neither: the first row and the first column give every voxel.
        let first_row = (0..side)
            .map(|i| self.voxel_at(frame, i, 0))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(beyond_range)?;
        let first_column = (0..side)
            .map(|j| self.voxel_at(frame, 0, j))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(beyond_range)?;
        let columns: Vec<i32> = first_row.iter().map(|p| p[axis_u]).collect();
        let rows: Vec<i32> = first_column.iter().map(|p| p[axis_v]).collect();
        let (Some(u_range), Some(v_range)) = (unit_steps(&columns), unit_steps(&rows)) else {
            return Ok(None);
        };
        let depth = first_row[0][axis_n];
        let mut lo = [0i32; 3];
        let mut hi = [0i32; 3];
        (lo[axis_u], hi[axis_u]) = u_range;
        (lo[axis_v], hi[axis_v]) = v_range;
        (lo[axis_n], hi[axis_n]) = (depth, depth + 1);
        let region = Box3::new(lo, hi);
        // Storage order of the box (x fastest): the offset of a voxel is the sum of its
        // column's and its row's parts.
        let size = region.size();
        let strides = [1, size[0] as usize, size[0] as usize * size[1] as usize];
        let offsets = |coords: &[i32], axis: usize| -> Vec<usize> {
            coords
                .iter()
                .map(|&c| (c - lo[axis]) as usize * strides[axis])
                .collect()
        };
        Ok(Some(AxisCut {
            region,
            column_offsets: offsets(&columns, axis_u),
            row_offsets: offsets(&rows, axis_v),
        }))
    }
}

fn beyond_range() -> Error {
    Error::invalid("--origin/--spacing", "the cut reaches beyond +-2^28 voxels")
}

/// The axis w lies along, when it is exactly a unit axis vector (either sign).
fn unit_axis(w: DVec3) -> Option<usize> {
    let a = w.to_array();
    let axis = a.iter().position(|c| c.abs() == 1.0)?;
    a.iter()
        .enumerate()
        .all(|(k, c)| k == axis || *c == 0.0)
        .then_some(axis)
}

/// The half-open range of `coords` when they step by +1 or by -1 throughout.
fn unit_steps(coords: &[i32]) -> Option<(i32, i32)> {
    let step = match coords {
        [a, b, ..] => b.checked_sub(*a)?,
        _ => 1,
    };
    let steady = (step == 1 || step == -1) && coords.windows(2).all(|w| w[1] - w[0] == step);
    let (first, last) = (*coords.first()?, *coords.last()?);
    steady.then_some((first.min(last), first.max(last) + 1))
}

/// An axis-aligned cut at spacing 1: its pixels are exactly the voxels of a one-voxel-thick
/// box, synthesized as a box (no per-pixel points, brick search or colour lookups) and
/// rearranged into the image.
struct AxisCut {
    region: Box3,
    /// The storage offset in `region` of column i's coordinate along u's axis (x fastest).
    column_offsets: Vec<usize>,
    /// The same for row j along v's axis.
    row_offsets: Vec<usize>,
}

impl AxisCut {
    /// The cut's image from the synthesized `region`.
    fn image(&self, region: Volume) -> Image {
        let channels = region.channels as usize;
        let side = self.column_offsets.len();
        let (width, height) = (side as u32, side as u32);
        // A z cut with the default frame lists the box in storage order: the image is the box.
        let in_order = self.column_offsets.iter().enumerate().all(|(i, &o)| o == i)
            && self
                .row_offsets
                .iter()
                .enumerate()
                .all(|(j, &o)| o == j * side);
        if in_order {
            return Image {
                width,
                height,
                channels: channels as u32,
                pixels: region.data,
            };
        }
        let mut img = Image::new(width, height, channels as u32);
        let rows_per_piece = (super::PARALLEL_PIECE / side).max(1);
        img.pixels
            .par_chunks_mut(side * channels)
            .with_min_len(rows_per_piece)
            .zip(&self.row_offsets)
            .for_each(|(row, &row_offset)| {
                for (pixel, &column_offset) in
                    row.chunks_exact_mut(channels).zip(&self.column_offsets)
                {
                    let at = (row_offset + column_offset) * channels;
                    pixel.copy_from_slice(&region.data[at..at + channels]);
                }
            });
        img
    }
}

/// A warm synthesis session for repeated cuts.
pub struct CutSession {
    synth: Synthesizer,
}

impl std::fmt::Debug for CutSession {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CutSession")
            .field("params", &self.synth.params)
            .field("color_channels", &self.synth.color_channels())
            .finish_non_exhaustive()
    }
}

impl CutSession {
    /// A session over `synth`, which keeps its device buffers between cuts.
    pub fn new(mut synth: Synthesizer) -> CutSession {
        synth.keep_buffers();
        CutSession { synth }
    }

    /// The cut image (colour channels of the solid).
    pub fn cut(&mut self, spec: &CutSpec) -> Result<Image> {
        cut(&mut self.synth, spec)
    }

    /// The synthesizer (e.g. for its statistics).
    pub fn synthesizer(&self) -> &Synthesizer {
        &self.synth
    }

    /// The synthesizer, to synthesize boxes of the same solid with the same warm state.
    pub fn synthesizer_mut(&mut self) -> &mut Synthesizer {
        &mut self.synth
    }

    /// The warm synthesizer back.
    pub fn into_synthesizer(self) -> Synthesizer {
        self.synth
    }
}

/// The cut `spec` of `synth`'s solid as an image (its colour channels): a warm session's cut
/// ([`CutSession`]), or a one-off.
pub fn cut(synth: &mut Synthesizer, spec: &CutSpec) -> Result<Image> {
    if let Some(axis_cut) = spec.axis_cut()? {
        let region = synth.synthesize_cut_box(axis_cut.region)?;
        let timer = std::time::Instant::now();
        let img = axis_cut.image(region);
        tracing::debug!("cut: image of a box in {:.1} ms", ms(timer));
        return Ok(img);
    }
    let timer = std::time::Instant::now();
    let voxels = spec.voxels()?;
    tracing::debug!("cut: points in {:.1} ms", ms(timer));
    let samples = synth.sample(&voxels, &|_, _| {})?;
    let timer = std::time::Instant::now();
    let channels = synth.color_channels() as usize;
    let mut img = Image::new(spec.size, spec.size, channels as u32);
    img.pixels
        .par_chunks_mut(channels * super::PARALLEL_PIECE)
        .zip(samples.par_chunks(super::PARALLEL_PIECE))
        .for_each(|(pixels, words)| {
            for (pixel, word) in pixels.chunks_exact_mut(channels).zip(words) {
                pixel.copy_from_slice(&word.to_le_bytes()[..channels]);
            }
        });
    tracing::debug!("cut: image in {:.1} ms", ms(timer));
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_aligned_frames_follow_the_conventions() {
        let spec = |normal, up| CutSpec {
            origin: [32.0, 32.0, 20.0],
            normal,
            up,
            size: 64,
            spacing: 1.0,
        };
        let (u, v, _) = spec([0.0, 0.0, 1.0], None).frame().unwrap();
        assert_eq!((u, v), (DVec3::X, DVec3::Y));
        let vox = spec([0.0, 0.0, 1.0], None).voxels().unwrap();
        assert_eq!(vox[0], [0, 0, 20]);
        assert_eq!(vox[64 * 3 + 5], [5, 3, 20]);
        // Normal along y: up defaults to +z.
        let (u, v, _) = spec([0.0, 2.0, 0.0], None).frame().unwrap();
        assert_eq!(v, DVec3::Z);
        assert!((u - DVec3::Z.cross(DVec3::Y)).length() < 1e-12);
        assert!(spec([0.0, 0.0, 0.0], None).frame().is_err());
        assert!(spec([0.0, 0.0, 1.0], Some([0.0, 0.0, 5.0]))
            .frame()
            .is_err());
        assert!(spec([f64::NAN, 0.0, 1.0], None).frame().is_err());
        // Any length but zero: a normal or up whose length overflows or underflows gives the
        // frame of the same direction at a usual length.
        let frame = |normal, up| spec(normal, up).frame().unwrap();
        let diagonal = frame([1.0, 1.0, 0.0], Some([0.0, 0.0, 1.0]));
        for scale in [1e308, 1e-20, 1e-300] {
            let scaled = frame([scale, scale, 0.0], Some([0.0, 0.0, scale]));
            assert_eq!(scaled, diagonal, "{scale}");
        }
        let zero_up = spec([0.0, 0.0, 1.0], Some([0.0; 3])).frame().unwrap_err();
        assert!(zero_up.to_string().contains("--up: must not be the zero vector"));
    }

    /// An axis-aligned cut at spacing 1 is taken as a box: the box holds exactly the voxels its
    /// pixels sample, and each pixel's offset in it is that pixel's voxel, for every orientation
    /// and sign, fractional origins and negative coordinates. Other cuts are not boxes.
    #[test]
    fn axis_cuts_are_the_boxes_of_their_voxels() {
        let normals = [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -3.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [2.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
        ];
        let ups = [
            None,
            Some([1.0, 0.0, 0.0]),
            Some([0.0, -1.0, 0.0]),
            Some([0.0, 0.0, -2.0]),
        ];
        let origins = [
            [32.0, 32.0, 20.0],
            [-7.3, 5.5, -0.25],
            [0.49999999999999994, 1.0e6 + 0.3, -3.0],
        ];
        let mut boxes = 0;
        for normal in normals {
            for up in ups {
                for origin in origins {
                    for size in [1, 6, 33] {
                        let spec = CutSpec {
                            origin,
                            normal,
                            up,
                            size,
                            spacing: 1.0,
                        };
                        if spec.frame().is_err() {
                            continue; // up along the normal
                        }
                        let voxels = spec.voxels().unwrap();
                        let Some(axis_cut) = spec.axis_cut().unwrap() else {
                            // Only where rounding makes two pixels sample one voxel (the origin
                            // just below 0.5: -0.5 + o rounds below 0, 0.5 + o to 1).
                            let distinct: std::collections::HashSet<_> = voxels.iter().collect();
                            assert!(distinct.len() < voxels.len(), "{spec:?} is a box");
                            assert_eq!(origin[0], 0.49999999999999994, "{spec:?}");
                            continue;
                        };
                        assert_eq!(axis_cut.region.voxels(), voxels.len() as u64, "{spec:?}");
                        let side = size as usize;
                        for (k, p) in voxels.iter().enumerate() {
                            let (i, j) = (k % side, k / side);
                            assert!(axis_cut.region.contains(*p), "{spec:?}: {p:?}");
                            assert_eq!(
                                axis_cut.column_offsets[i] + axis_cut.row_offsets[j],
                                axis_cut.region.index(*p),
                                "{spec:?}: pixel {i},{j}"
                            );
                        }
                        boxes += 1;
                    }
                }
            }
        }
        // Every cut but those with a column or row stepping twice onto one voxel.
        assert!(boxes >= 6 * 3 * 2 * 3, "{boxes}");
        let not_boxes = [
            ([0.0, 0.0, 1.0], 2.0),
            ([0.0, 0.0, 1.0], 0.5),
            ([0.0, 0.3, 1.0], 1.0),
            ([1.0, 1.0, 0.0], 1.0),
        ];
        for (normal, spacing) in not_boxes {
            let spec = CutSpec {
                origin: [3.5, 2.0, 1.0],
                normal,
                up: None,
                size: 16,
                spacing,
            };
            assert!(spec.axis_cut().unwrap().is_none(), "{spec:?}");
        }
    }
}
