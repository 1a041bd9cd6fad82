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

use super::Synthesizer;
use crate::error::{Error, Result};
use crate::exemplar::Image;
use glam::DVec3;
use rayon::prelude::*;

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
        if !(self.spacing.is_finite() && self.spacing > 0.0 && self.spacing <= 1024.0) {
            return Err(Error::invalid(
                format!("--spacing {}", self.spacing),
                "must be a number in (0, 1024]",
            ));
        }
        let n = DVec3::from_array(self.normal);
        if !finite(&self.normal) || n.length() < 1e-9 {
            return Err(Error::invalid(
                "--normal",
                "must be a finite, non-zero vector",
            ));
        }
        let n = n.normalize();
        let up = match self.up {
            Some(u) => {
                if !finite(&u) {
                    return Err(Error::invalid("--up", "must be finite"));
                }
                DVec3::from_array(u)
            }
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
        let (u, v, _) = self.frame()?;
        let o = DVec3::from_array(self.origin);
        let (n, s) = (self.size as f64, self.spacing);
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
                    let p =
                        o + (i as f64 + 0.5 - n / 2.0) * s * u + (j as f64 + 0.5 - n / 2.0) * s * v;
                    let f = p.floor();
                    if f.abs().max_element() > (1 << 28) as f64 {
                        return false;
                    }
                    *voxel = [f.x as i32, f.y as i32, f.z as i32];
                }
                true
            });
        if !inside {
            return Err(Error::invalid(
                "--origin/--spacing",
                "the cut reaches beyond +-2^28 voxels",
            ));
        }
        Ok(out)
    }
}

/// A warm synthesis session for repeated cuts.
pub struct CutSession {
    synth: Synthesizer,
}

impl CutSession {
    /// A session over `synth`, which keeps its device buffers between cuts.
    pub fn new(mut synth: Synthesizer) -> CutSession {
        synth.keep_buffers();
        CutSession { synth }
    }

    /// The cut image (colour channels of the solid).
    pub fn cut(&mut self, spec: &CutSpec) -> Result<Image> {
        let timer = std::time::Instant::now();
        let voxels = spec.voxels()?;
        tracing::debug!(
            "cut: points in {:.1} ms",
            timer.elapsed().as_secs_f64() * 1e3
        );
        let samples = self.synth.sample(&voxels, &|_, _| {})?;
        let timer = std::time::Instant::now();
        let channels = self.synth.color_channels() as usize;
        let mut img = Image::new(spec.size, spec.size, channels as u32);
        img.pixels
            .par_chunks_mut(channels * super::PARALLEL_PIECE)
            .zip(samples.par_chunks(super::PARALLEL_PIECE))
            .for_each(|(pixels, words)| {
                for (pixel, word) in pixels.chunks_exact_mut(channels).zip(words) {
                    pixel.copy_from_slice(&word.to_le_bytes()[..channels]);
                }
            });
        tracing::debug!(
            "cut: image in {:.1} ms",
            timer.elapsed().as_secs_f64() * 1e3
        );
        Ok(img)
    }

    /// The synthesizer (e.g. for its statistics).
    pub fn synthesizer(&self) -> &Synthesizer {
        &self.synth
    }

    /// The synthesizer, to synthesize boxes of the same solid with the same warm state.
    pub fn synthesizer_mut(&mut self) -> &mut Synthesizer {
        &mut self.synth
    }
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
    }
}
