//! What the `lapped_render` pipeline and its CPU reference read: a camera and a scene of
//! vertex streams and 3D textures (built from a lapped model by `lapped::scene`).

use glam::{DMat4, DVec3, Mat4};

/// Floats per vertex: position, normal, texture coordinate, mask index.
pub const VERTEX_FLOATS: usize = 10;
/// A lapped model ready to draw: the vertex streams ([`VERTEX_FLOATS`] floats per vertex:
/// position, smooth normal, texture coordinate, mask index) of the depth pre-pass (one copy of each
/// boundary face) and of the layers (one copy per face and layer, sorted by patch), the solid
/// exemplar (RGBA, `exemplar_size`^3) and the masks (one byte per texel, `mask_size`^3 each,
/// stacked along z).
pub struct RenderScene<'a> {
    pub prepass: Vec<f32>,
    pub layered: Vec<f32>,
    pub exemplar_size: u32,
    pub exemplar_rgba: &'a [u8],
    pub mask_size: u32,
    pub mask_count: u32,
    pub mask_alpha: Vec<u8>,
    /// Texture coordinates' depth clamps (1) or wraps (0): the model's texture varies with depth.
    pub depth_varying: bool,
}

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
