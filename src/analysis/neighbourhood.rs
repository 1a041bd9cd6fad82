//! Gathering 2D neighbourhood vectors and strips from exemplar images.
//!
//! The neighbourhood vectors' layout is the `project` kernel's (`contract::pca`).

use super::frame::HALF;
use crate::exemplar::{Border, Image};

pub use crate::contract::pca::gather;

/// The horizontal strip (row through the pixel, u varying) of pixel (x, y).
pub fn h_strip(img: &Image, border: Border, x: u32, y: u32, out: &mut Vec<u8>) {
    for du in -HALF..=HALF {
        out.extend_from_slice(img.at_border(x as i32 + du, y as i32, border));
    }
}

/// The vertical strip (column through the pixel, v varying) of pixel (x, y).
pub fn v_strip(img: &Image, border: Border, x: u32, y: u32, out: &mut Vec<u8>) {
    for dv in -HALF..=HALF {
        out.extend_from_slice(img.at_border(x as i32, y as i32 + dv, border));
    }
}

/// All strips of an image, `kind` = h_strip or v_strip, flattened (pixel-major).
pub fn all_strips(
    img: &Image,
    border: Border,
    kind: fn(&Image, Border, u32, u32, &mut Vec<u8>),
) -> Vec<u8> {
    let mut out = Vec::with_capacity(img.pixel_count() * 5 * img.channels as usize);
    for y in 0..img.height {
        for x in 0..img.width {
            kind(img, border, x, y, &mut out);
        }
    }
    out
}
