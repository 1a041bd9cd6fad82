//! A `.gsolid` file of either kind, plain or region-separated (told apart by its magic), as the
//! renderers take it: evaluation on a backend, 8-bit output, and its memory check.

use super::regions::{self, Blend, RegionSolid};
use super::{detail, format, quantize, GradientSolid, Query};
use crate::backend::Compute;
use crate::error::{Error, Result};
use std::path::Path;

/// A plain or a region-separated gradient solid (told apart by the file's magic).
pub enum GradientFile {
    Plain(GradientSolid),
    Regions(RegionSolid),
}

impl GradientFile {
    /// Output (colour) channels.
    pub fn channels(&self) -> u32 {
        match self {
            GradientFile::Plain(s) => s.channels - s.detail,
            GradientFile::Regions(r) => r.channels(),
        }
    }
    pub fn extent(&self) -> [u32; 3] {
        match self {
            GradientFile::Plain(s) => s.extent(),
            GradientFile::Regions(r) => r.extent(),
        }
    }

    /// The plain solid, or a region solid's colour set (its three grids share the size).
    fn grid(&self) -> &GradientSolid {
        match self {
            GradientFile::Plain(s) => s,
            GradientFile::Regions(r) => &r.positive,
        }
    }

    /// The voxels the solid stands for ([`GradientSolid::size`]): a render's default volume.
    pub fn size(&self) -> [u32; 3] {
        self.grid().size
    }

    /// Whether the solid repeats with period [`Self::size`].
    pub fn periodic(&self) -> bool {
        self.grid().periodic
    }

    /// A periodic solid's `query` with every point wrapped into its period, as explicit points;
    /// `None` where nothing needs wrapping (a solid that is not periodic, or every point
    /// inside the period already).
    fn wrapped(&self, query: &Query) -> Option<Query> {
        if !self.periodic() {
            return None;
        }
        let period = self.size().map(f64::from);
        let inside = |p: [f64; 3]| (0..3).all(|a| p[a] >= 0.0 && p[a] < period[a]);
        let wrap = |p: [f64; 3]| {
            let w: [f64; 3] = std::array::from_fn(|a| p[a].rem_euclid(period[a]));
            // (rem_euclid of a tiny negative number can round up to the period itself.)
            std::array::from_fn(|a| (if w[a] < period[a] { w[a] } else { 0.0 }) as f32)
        };
        let f64s = |v: [f32; 3]| v.map(f64::from);
        match query {
            Query::Grid { origin, a, b, c, n } => {
                let (o, a, b, c) = (f64s(*origin), f64s(*a), f64s(*b), f64s(*c));
                let at = |i: u32, j: u32, k: u32| -> [f64; 3] {
                    std::array::from_fn(|x| {
                        o[x] + i as f64 * a[x] + j as f64 * b[x] + k as f64 * c[x]
                    })
                };
                // The grid is affine in (i, j, k): its extreme points are its corners.
                let last = n.map(|v| v.saturating_sub(1));
                let corners_inside = (0..8).all(|m| {
                    let pick = |bit: u32, l: u32| if m >> bit & 1 == 1 { l } else { 0 };
                    inside(at(pick(0, last[0]), pick(1, last[1]), pick(2, last[2])))
                });
                if corners_inside {
                    return None;
                }
                let mut points = Vec::with_capacity(query.len());
                for k in 0..n[2] {
                    for j in 0..n[1] {
                        for i in 0..n[0] {
                            points.push(wrap(at(i, j, k)));
                        }
                    }
                }
                Some(Query::Points(points))
            }
            Query::Points(points) => {
                let points: Vec<[f64; 3]> = points.iter().map(|&p| f64s(p)).collect();
                if points.iter().all(|&p| inside(p)) {
                    return None;
                }
                Some(Query::Points(points.into_iter().map(wrap).collect()))
            }
        }
    }

    /// The volume [0, n) at integer voxels as 8-bit values: [`Self::eval_u8`], except that a
    /// periodic solid evaluates one period (or less) and repeats it, voxel for voxel.
    pub fn render_volume_u8(
        &self,
        n: [u32; 3],
        compute: &Compute,
        blend: Blend,
        grain: bool,
    ) -> Result<Vec<u8>> {
        let tile = match self.periodic() {
            true => std::array::from_fn(|a| n[a].min(self.size()[a])),
            false => n,
        };
        let values = self.eval_u8(&Query::volume(tile), compute, blend, grain)?;
        if tile == n {
            return Ok(values);
        }
        let c = self.channels() as usize;
        let mut out = Vec::with_capacity(n.iter().map(|&v| v as usize).product::<usize>() * c);
        for z in 0..n[2] {
            for y in 0..n[1] {
                let row = ((z % tile[2]) * tile[1] + y % tile[1]) as usize * tile[0] as usize;
                for x in 0..n[0] {
                    let at = (row + (x % tile[0]) as usize) * c;
                    out.extend_from_slice(&values[at..at + c]);
                }
            }
        }
        Ok(out)
    }
    /// Kernel `tricubic_eval` on the chosen backend (float results; rounding may differ by one
    /// 8-bit level between backends where a value lies within the tolerance of a .5).
    pub fn eval(
        &self,
        query: &Query,
        compute: &Compute,
        blend: Blend,
        grain: bool,
    ) -> Result<Vec<f32>> {
        if let Some(wrapped) = self.wrapped(query) {
            return self.eval(&wrapped, compute, blend, grain);
        }
        match self {
            GradientFile::Plain(s) => {
                let values = compute.tricubic_eval(s, query)?;
                Ok(if s.detail > 0 {
                    detail::colours(s, query, &values, grain)
                } else {
                    values
                })
            }
            GradientFile::Regions(r) => r.eval_query(query, compute, blend),
        }
    }

    /// [`GradientFile::eval`] as 8-bit values ([`quantize`]d): plain solids through
    /// [`crate::gradient::render::render_u8`] (the kernel quantizes on the GPU), the others
    /// quantize the float results.
    pub fn eval_u8(
        &self,
        query: &Query,
        compute: &Compute,
        blend: Blend,
        grain: bool,
    ) -> Result<Vec<u8>> {
        if let Some(wrapped) = self.wrapped(query) {
            return self.eval_u8(&wrapped, compute, blend, grain);
        }
        if let GradientFile::Plain(s) = self {
            if s.detail == 0 {
                return crate::gradient::render::render_u8(s, query, compute);
            }
        }
        let values = self.eval(query, compute, blend, grain)?;
        Ok(values.into_iter().map(quantize).collect())
    }

    /// Read a `.gsolid` file of either kind.
    pub fn load(path: &Path) -> Result<GradientFile> {
        let bytes = crate::io::input::read(path)?;
        let name = path.display().to_string();
        if regions::is_region_file(&bytes) {
            Ok(GradientFile::Regions(RegionSolid::from_bytes(
                &bytes, &name,
            )?))
        } else {
            Ok(GradientFile::Plain(format::from_bytes(&bytes, &name)?))
        }
    }

    /// Refuse a render volume before allocating it: its points must fit the kernels' 32-bit
    /// indices, and the output (plus the float values of the paths that are not quantized in the
    /// kernel) must fit the available memory.
    pub fn check_render_memory(&self, n: [u32; 3]) -> Result<()> {
        let points = n.iter().map(|&v| v as u64).product::<u64>();
        let what = || format!("--size {}", n[0]);
        if points > u32::MAX as u64 {
            return Err(Error::invalid(
                what(),
                "a rendered volume holds at most 2^32 - 1 voxels (1625^3)",
            ));
        }
        // Bytes per voxel: the output, plus the GPU's packed words for a plain solid (quantized as
        // it is evaluated), or the float values of the other paths (a region solid evaluates three
        // grids).
        let channels = self.channels() as u64;
        let per_voxel = match self {
            GradientFile::Plain(s) if s.detail == 0 => channels + 4,
            GradientFile::Plain(_) => channels * 9,
            GradientFile::Regions(_) => channels + 4 * (1 + 3 * channels),
        };
        let estimate = points * per_voxel;
        let available = crate::util::memory::available_memory();
        if estimate > available {
            return Err(Error::invalid(
                what(),
                format!(
                    "needs about {} of memory, {}",
                    crate::util::memory::human_bytes(estimate),
                    crate::util::memory::available_text(available)
                ),
            ));
        }
        Ok(())
    }
}
