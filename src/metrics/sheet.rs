//! Contact sheets: the exemplar beside orthogonal slices of the volume, for people to look at.
//!
//! Layout, at an integer zoom: first column the exemplar(s) (Ex, then Ey and Ez when they differ);
//! then one column per axis (x, y, z) holding that axis's middle slice on the first row and its
//! quarter and three-quarter slices below. Slices use the exemplar frame (see `slices`).

use super::slices::slice;
use crate::exemplar::Image;
use crate::volume::Volume;

pub fn contact_sheet(volume: &Volume, exemplars: &[Image]) -> image::RgbaImage {
    let d = volume.dims();
    let biggest = d
        .iter()
        .copied()
        .chain(exemplars.iter().map(|e| e.width.max(e.height)))
        .max()
        .unwrap_or(1);
    // Each panel at its own integer zoom, so small volumes are as legible as large exemplars.
    let cell = biggest.max(256);
    let gap = 4;
    let rows = 3u32.max(exemplars.len() as u32);
    let mut sheet = image::RgbaImage::from_pixel(
        4 * (cell + gap) + gap,
        rows * (cell + gap) + gap,
        image::Rgba([32, 32, 32, 255]),
    );
    let mut blit = |img: &Image, col: u32, row: u32| {
        let zoom = (cell / img.width.max(img.height)).clamp(1, 16);
        let rgba = img.to_rgba8();
        for y in 0..img.height * zoom {
            for x in 0..img.width * zoom {
                let px = *rgba.get_pixel(x / zoom, y / zoom);
                sheet.put_pixel(
                    gap + col * (cell + gap) + x,
                    gap + row * (cell + gap) + y,
                    px,
                );
            }
        }
    };
    for (i, e) in exemplars.iter().enumerate() {
        blit(e, 0, i as u32);
    }
    for axis in 0..3 {
        let n = d[axis];
        for (row, index) in [n / 2, n / 4, 3 * n / 4].into_iter().enumerate() {
            blit(
                &slice(volume, axis, index.min(n - 1)),
                axis as u32 + 1,
                row as u32,
            );
        }
    }
    sheet
}
