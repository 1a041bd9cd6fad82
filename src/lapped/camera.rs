//! The orbit camera of `lapped render`, placed around a model (the camera itself is
//! `contract::lapped::Camera`, which the render kernel and its reference read).

use super::model::LstModel;
use crate::error::{Error, Result};
use glam::DVec3;

pub use crate::contract::lapped::{Camera, FOV_DEGREES};

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
}
