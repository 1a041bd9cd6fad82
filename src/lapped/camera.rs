//! The orbit camera of `lapped render` and the surface shading both renderers share, so the GPU
//! render can be checked against a CPU ray cast ([`reference_pixel`]).

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

/// Headlight shading factor: ambient plus diffuse towards the eye (same formula in the shader).
pub fn shading(normal: DVec3, to_eye: DVec3) -> f64 {
    0.3 + 0.7 * normal.normalize().dot(to_eye.normalize()).abs()
}

/// The colour the renderer should give pixel (x, y): ray cast against the boundary faces, the
/// layers of the hit tet composited, then shaded. `None` where the ray misses the model.
pub fn reference_pixel(
    model: &LstModel,
    faces: &[([u32; 3], u32)],
    camera: &Camera,
    size: u32,
    x: u32,
    y: u32,
) -> Option<[f64; 3]> {
    let (o, d) = camera.ray(x, y, size);
    let mut best: Option<(f64, usize)> = None;
    for (i, (f, _)) in faces.iter().enumerate() {
        let [a, b, c] = f.map(|v| model.mesh.vertices[v as usize]);
        // Moller-Trumbore, front faces only (the renderer culls back faces): det = -d . n.
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det < 1e-12 {
            continue;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let t = e2.dot(q) / det;
        if u < 0.0 || v < 0.0 || u + v > 1.0 || t <= 0.0 {
            continue;
        }
        if best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, i));
        }
    }
    let (t, i) = best?;
    let (f, tet) = faces[i];
    let hit = o + d * t;
    let b = model
        .mesh
        .barycentric(tet as usize, hit)
        .map(|x| x.max(0.0));
    let sum: f64 = b.iter().sum();
    let rgba = model.shade(tet as usize, b.map(|x| (x / sum) as f32));
    let [a, bb, c] = f.map(|v| model.mesh.vertices[v as usize]);
    let k = shading((bb - a).cross(c - a), camera.eye - hit);
    Some([rgba[0] as f64 * k, rgba[1] as f64 * k, rgba[2] as f64 * k])
}
