//! The candidate slab (paper 4.3): each exemplar pixel's best triple thickens the exemplar into a
//! slab 5 voxels deep along the plane's normal. It initializes synthesis (tiled); here it is also
//! rendered so a person can look at it (cf. the paper's Fig. 5).

use super::frame::{next, unpack, HALF};
use super::Analysis;
use crate::exemplar::Image;

/// Colour of the slab voxel at depth `d` (-2..=2) along the normal of E_a above pixel `p`: the
/// average of E_a at p, E_{a+1} at c_{a+1} + (0, d) and E_{a+2} at c_{a+2} + (d, 0) (the normal is
/// v in E_{a+1} and u in E_{a+2}, see `frame`).
pub fn slab_layer(analysis: &Analysis, a: usize, level: usize, d: i32) -> Image {
    let ex = |e: usize| &analysis.exemplar(e).levels[level].image;
    let img_a = ex(a);
    let colors = analysis.color_channels;
    let mut out = Image::new(img_a.width, img_a.height, colors);
    let border = analysis.border;
    for y in 0..img_a.height {
        for x in 0..img_a.width {
            let p = (y * img_a.width + x) as usize;
            let t = analysis.slab_triple(a, level, p);
            let (x1, y1) = unpack(t[next(a)]);
            let (x2, y2) = unpack(t[next(next(a))]);
            let c0 = img_a.at(x, y);
            let c1 = ex(next(a)).at_border(x1 as i32, y1 as i32 + d, border);
            let c2 = ex(next(next(a))).at_border(x2 as i32 + d, y2 as i32, border);
            let dst = &mut out.pixels[p * colors as usize..][..colors as usize];
            for k in 0..colors as usize {
                dst[k] = ((c0[k] as u32 + c1[k] as u32 + c2[k] as u32 + 1) / 3) as u8;
            }
        }
    }
    out
}

/// A sheet: one row per analysed level (finest first, each scaled up to the finest size by pixel
/// repetition), one column per slab depth -2..=2, 2-pixel gaps.
pub fn slab_sheet(analysis: &Analysis, a: usize) -> image::RgbaImage {
    let levels = &analysis.exemplar(a).levels;
    let (w, h) = (levels[0].image.width, levels[0].image.height);
    let gap = 2;
    let depths = 2 * HALF as u32 + 1;
    let mut sheet = image::RgbaImage::from_pixel(
        depths * (w + gap) + gap,
        levels.len() as u32 * (h + gap) + gap,
        image::Rgba([40, 40, 40, 255]),
    );
    for level in 0..levels.len() {
        let scale = 1u32 << level;
        for (col, d) in (-HALF..=HALF).enumerate() {
            let layer = slab_layer(analysis, a, level, d).to_rgba8();
            for y in 0..h {
                for x in 0..w {
                    let px = layer.get_pixel(
                        (x / scale).min(layer.width() - 1),
                        (y / scale).min(layer.height() - 1),
                    );
                    sheet.put_pixel(
                        gap + col as u32 * (w + gap) + x,
                        gap + level as u32 * (h + gap) + y,
                        *px,
                    );
                }
            }
        }
    }
    sheet
}
