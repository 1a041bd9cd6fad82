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
        let problem = if !(az.is_finite() && el.is_finite() && dist.is_finite()) {
            Some("numbers must be finite")
        } else if el.abs() >= 90.0 {
            // The orbit camera keeps +y up, which a view straight up or down does not have.
            Some("the elevation EL must be strictly between -90 and 90 degrees")
        } else if dist <= 1.0 {
            Some("the distance DIST must be over 1 bounding radius (outside the model)")
        } else {
            None
        };
        if let Some(problem) = problem {
            return Err(Error::invalid(format!("--camera {spec}"), problem));
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
