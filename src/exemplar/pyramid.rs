//! Gaussian pyramids. Level 0 is the finest image; each coarser level halves the size.
//!
//! The coarse pixel i covers fine pixels 2i and 2i+1 (the convention of coordinate inheritance in
//! synthesis: child = 2 * parent + offset), so the filter is centred on 2i + 1/2: taps 2i-1..2i+2
//! with binomial weights 1 3 3 1 (/8) per axis. Integer arithmetic with round-half-up keeps it
//! exact and identical everywhere.

use super::{Border, Image};

/// One 2x reduction.
pub fn reduce(img: &Image, border: Border) -> Image {
    let (w, h, c) = (img.width, img.height, img.channels as usize);
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    const TAPS: [(i32, u32); 4] = [(-1, 1), (0, 3), (1, 3), (2, 1)];
    // Horizontal pass into u16 (sum of weights 8: values up to 2040).
    let mut horiz = vec![0u16; (cw * h) as usize * c];
    for y in 0..h {
        for x in 0..cw {
            for (dx, wgt) in TAPS {
                let sx = border.resolve(2 * x as i32 + dx, w);
                let src = img.at(sx, y);
                let dst = &mut horiz[((y * cw + x) as usize) * c..][..c];
                for k in 0..c {
                    dst[k] += src[k] as u16 * wgt as u16;
                }
            }
        }
    }
    let mut out = Image::new(cw, ch, img.channels);
    for y in 0..ch {
        for x in 0..cw {
            let mut acc = vec![0u32; c];
            for (dy, wgt) in TAPS {
                let sy = border.resolve(2 * y as i32 + dy, h);
                let src = &horiz[((sy * cw + x) as usize) * c..][..c];
                for k in 0..c {
                    acc[k] += src[k] as u32 * wgt;
                }
            }
            let dst = &mut out.pixels[((y * cw + x) as usize) * c..][..c];
            for k in 0..c {
                dst[k] = ((acc[k] + 32) / 64) as u8;
            }
        }
    }
    out
}

/// `levels` images, finest first.
pub fn gaussian_pyramid(img: &Image, levels: usize, border: Border) -> Vec<Image> {
    let mut out = vec![img.clone()];
    while out.len() < levels {
        let next = reduce(out.last().unwrap(), border);
        out.push(next);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_image_stays_constant_and_sizes_halve_up() {
        let mut img = Image::new(17, 16, 3);
        img.pixels.iter_mut().for_each(|p| *p = 77);
        for border in [Border::Wrap, Border::Mirror] {
            let p = gaussian_pyramid(&img, 4, border);
            assert_eq!(
                p.iter().map(|l| (l.width, l.height)).collect::<Vec<_>>(),
                vec![(17, 16), (9, 8), (5, 4), (3, 2)]
            );
            assert!(p[3].pixels.iter().all(|&v| v == 77));
        }
    }

    #[test]
    fn mirror_resolve_reflects_without_repeating_the_edge() {
        let b = Border::Mirror;
        let got: Vec<u32> = (-3..8).map(|c| b.resolve(c, 5)).collect();
        assert_eq!(got, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        assert_eq!(b.resolve(-7, 2), 1);
        assert_eq!(Border::Wrap.resolve(-1, 5), 4);
    }
}
