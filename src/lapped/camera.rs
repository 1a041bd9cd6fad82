//! The orbit camera of `lapped render` (GPU: `crate::gpu::lapped_render`; CPU reference ray cast:
//! `crate::cpu::lapped_render`).

use super::model::LstModel;
use crate::error::{Error, Result};
use glam::{DMat4, DVec3, Mat4};

/// Vertical field of view, degrees.
pub const FOV_DEGREES: f64 = 35.0;

/// A camera orbiting the model's bounding-sphere centre, y up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub near: f64,
    pub far: f64,
}

impl Camera {
    /// From `AZ,EL[,DIST]`: azimuth around +y from +z and elevation in degrees, distance in
    /// multiples of the bounding radius (default 2.6, which frames the model at 35 degrees).
    pub fn orbit(model: &LstModel, spec: &str) -> Result<Camera> {
        let bad = || {
            Error::invalid(
                format!("--camera {spec}"),
                "expected AZ,EL or AZ,EL,DIST (degrees, degrees, radii; DIST > 1)",
            )
        };
        let v: Vec<f64> = spec
            .split(',')
            .map(|t| t.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| bad())?;
        let (az, el, dist) = match v.as_slice() {
            [a, e] => (*a, *e, 2.6),
            [a, e, d] => (*a, *e, *d),
            _ => return Err(bad()),
        };
        if !(az.is_finite() && el.is_finite() && dist.is_finite() && dist > 1.0 && el.abs() < 90.0)
        {
            return Err(bad());
        }
        let (lo, hi) = model
            .mesh
            .vertices
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), p| {
                (l.min(*p), h.max(*p))
            });
        let center = (lo + hi) / 2.0;
        let radius = ((hi - lo).length() / 2.0).max(1e-9);
        let (az, el) = (az.to_radians(), el.to_radians());
        let dir = DVec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
        Ok(Camera {
            eye: center + dir * dist * radius,
            target: center,
            near: (dist - 1.0) * radius * 0.5,
            far: (dist + 1.0) * radius * 1.5,
        })
    }

    /// World to clip space (wgpu conventions: depth in [0, 1]), square aspect.
    pub fn view_proj(&self) -> DMat4 {
        let proj = glam::dcamera::rh::proj::directx::perspective(
            FOV_DEGREES.to_radians(),
            1.0,
            self.near,
            self.far,
        );
        proj * glam::dcamera::rh::view::look_at_mat4(self.eye, self.target, DVec3::Y)
    }

    pub fn view_proj_f32(&self) -> Mat4 {
        self.view_proj().as_mat4()
    }

    /// The world-space ray through the centre of pixel (x, y) of a size x size image.
    pub fn ray(&self, x: u32, y: u32, size: u32) -> (DVec3, DVec3) {
        let inv = self.view_proj().inverse();
        let ndc_x = (x as f64 + 0.5) / size as f64 * 2.0 - 1.0;
        let ndc_y = 1.0 - (y as f64 + 0.5) / size as f64 * 2.0;
        let near = inv.project_point3(DVec3::new(ndc_x, ndc_y, 0.0));
        let far = inv.project_point3(DVec3::new(ndc_x, ndc_y, 1.0));
        (near, (far - near).normalize())
    }
}
