//! Rendering a PTM under chosen lights (kernel `ptm_relight` on the selected backend) into
//! images, and contact sheets of a ring of lights.

use super::Lighting;
use super::Ptm;
use crate::backend::Compute;
use crate::error::Result;

/// r, g, b per pixel (unit intensity, unclamped) under `light`, on `compute`.
pub fn relight(compute: &Compute, ptm: &Ptm, light: &Lighting) -> Result<Vec<f32>> {
    compute.ptm_relight(ptm, light)
}

/// Unit-intensity RGB values as an 8-bit image (clamped, rounded).
pub fn to_image(width: u32, height: u32, rgb: &[f32]) -> image::RgbaImage {
    let q = |v: f32| (v * 255.0).round().clamp(0.0, 255.0) as u8;
    image::RgbaImage::from_fn(width, height, |x, y| {
        let i = 3 * (y as usize * width as usize + x as usize);
        image::Rgba([q(rgb[i]), q(rgb[i + 1]), q(rgb[i + 2]), 255])
    })
}

/// `n` lights evenly spaced in azimuth (starting at +u, counter-clockwise) at `elevation_deg`
/// above the surface.
pub fn ring(n: usize, elevation_deg: f64, specular: f32) -> Vec<Lighting> {
    let r = elevation_deg.to_radians().cos();
    (0..n)
        .map(|i| {
            let phi = std::f64::consts::TAU * i as f64 / n as f64;
            Lighting {
                lu: (r * phi.cos()) as f32,
                lv: (r * phi.sin()) as f32,
                specular,
            }
        })
        .collect()
}

/// A contact sheet: the PTM under each light, in a grid of ceil(sqrt(n)) columns (row-major, 4
/// pixel dark gutters). The GPU path uploads the texels once.
pub fn contact_sheet(
    compute: &Compute,
    ptm: &Ptm,
    lights: &[Lighting],
    progress: &mut dyn FnMut(usize, usize),
) -> Result<image::RgbaImage> {
    const GUTTER: u32 = 4;
    let cols = (lights.len() as f64).sqrt().ceil().max(1.0) as u32;
    let rows = (lights.len() as u32).div_ceil(cols).max(1);
    let (w, h) = (ptm.width, ptm.height);
    let mut sheet = image::RgbaImage::from_pixel(
        cols * (w + GUTTER) + GUTTER,
        rows * (h + GUTTER) + GUTTER,
        image::Rgba([24, 24, 24, 255]),
    );
    let resident = compute.resident_ptm(ptm);
    for (k, light) in lights.iter().enumerate() {
        let rgb = resident.relight(light)?;
        let img = to_image(w, h, &rgb);
        let (cx, cy) = (k as u32 % cols, k as u32 / cols);
        image::imageops::replace(
            &mut sheet,
            &img,
            (GUTTER + cx * (w + GUTTER)) as i64,
            (GUTTER + cy * (h + GUTTER)) as i64,
        );
        progress(k + 1, lights.len());
    }
    Ok(sheet)
}
