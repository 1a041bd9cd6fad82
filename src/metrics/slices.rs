//! Slices of a volume, laid out in the exemplar frame: the slice perpendicular to axis a has
//! columns along axis a+1 and rows along a+2 (x: (y, z); y: (z, x); z: (x, y)), so it compares
//! directly with E_a.

use crate::exemplar::Image;
use crate::volume::Volume;

/// The slice perpendicular to `axis` at `index`.
pub fn slice(v: &Volume, axis: usize, index: u32) -> Image {
    let d = v.dims();
    let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut img = Image::new(d[ua], d[va], v.channels);
    let c = v.channels as usize;
    for row in 0..d[va] {
        for col in 0..d[ua] {
            let mut p = [0u32; 3];
            p[axis] = index;
            p[ua] = col;
            p[va] = row;
            let dst = ((row * d[ua] + col) as usize) * c;
            img.pixels[dst..dst + c].copy_from_slice(v.at(p[0], p[1], p[2]));
        }
    }
    img
}

/// `count` slices perpendicular to `axis`, evenly spaced strictly inside the volume.
pub fn axis_slices(v: &Volume, axis: usize, count: u32) -> Vec<Image> {
    let n = v.dims()[axis];
    (1..=count)
        .map(|i| slice(v, axis, (i * n / (count + 1)).min(n - 1)))
        .collect()
}

/// Split an image into two halves along its longer side.
pub fn halves(img: &Image) -> (Image, Image) {
    let crop = |x0: u32, y0: u32, w: u32, h: u32| {
        let mut out = Image::new(w, h, img.channels);
        let c = img.channels as usize;
        for y in 0..h {
            for x in 0..w {
                let d = ((y * w + x) as usize) * c;
                out.pixels[d..d + c].copy_from_slice(img.at(x0 + x, y0 + y));
            }
        }
        out
    };
    if img.width >= img.height {
        let w = img.width / 2;
        (
            crop(0, 0, w, img.height),
            crop(w, 0, img.width - w, img.height),
        )
    } else {
        let h = img.height / 2;
        (
            crop(0, 0, img.width, h),
            crop(0, h, img.width, img.height - h),
        )
    }
}
