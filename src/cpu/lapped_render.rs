//! CPU reference of the render pipeline `wgsl/lapped_render.wgsl`: the colour the GPU render of an
//! LST model should give a pixel, by a ray cast against the boundary faces (front faces only, as
//! the renderer culls back faces), the layers of the hit tet composited (the caller's `shade`:
//! the model's own compositing, `lapped::model::LstModel::shade`) and the shader's headlight
//! shading of the interpolated smooth normal. Used by kernels-tests, pixel by pixel.

use crate::contract::lapped::Camera;
use glam::DVec3;

/// Headlight shading factor: ambient plus diffuse towards the eye (same formula in the shader).
pub fn shading(normal: DVec3, to_eye: DVec3) -> f64 {
    0.3 + 0.7 * normal.normalize().dot(to_eye.normalize()).abs()
}

/// The colour the renderer should give pixel (x, y): ray cast against the boundary faces
/// (`vertices` indexed by `faces`, each with its tet), the layers of the hit tet composited by
/// `shade(tet, hit point)`, then shaded. `None` where the ray misses the model.
#[allow(clippy::too_many_arguments)]
pub fn reference_pixel(
    vertices: &[DVec3],
    faces: &[([u32; 3], u32)],
    normals: &[DVec3],
    camera: &Camera,
    size: u32,
    x: u32,
    y: u32,
    shade: impl Fn(u32, DVec3) -> [f32; 4],
) -> Option<[f64; 3]> {
    let (o, d) = camera.ray(x, y, size);
    let mut best: Option<(f64, usize, f64, f64)> = None;
    for (i, (f, _)) in faces.iter().enumerate() {
        let [a, b, c] = f.map(|v| vertices[v as usize]);
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
        if best.is_none_or(|(bt, ..)| t < bt) {
            best = Some((t, i, u, v));
        }
    }
    let (t, i, u, v) = best?;
    let (f, tet) = faces[i];
    let hit = o + d * t;
    let rgba = shade(tet, hit);
    // The smooth normal, interpolated like the rasterizer does (barycentric in the face).
    let [na, nb, nc] = f.map(|v| normals[v as usize]);
    let normal = (1.0 - u - v) * na + u * nb + v * nc;
    let k = shading(normal, camera.eye - hit);
    Some([rgba[0] as f64 * k, rgba[1] as f64 * k, rgba[2] as f64 * k])
}
