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
    /// Kernel `tricubic_eval` on the chosen backend (float results; rounding may differ by one
    /// 8-bit level between backends where a value lies within the tolerance of a .5).
    pub fn eval(
        &self,
        query: &Query,
        compute: &Compute,
        blend: Blend,
        grain: bool,
    ) -> Result<Vec<f32>> {
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
