//! Procedural, tileable exemplars: the built-in default exemplar and the repository's test
//! fixtures are made here, so nothing in the tests depends on third-party images.

use super::Image;
use crate::util::hash::{mix64, SeededRng};

fn unit(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Periodic Voronoi cells ("cobblestones"): rounded stones of varied colour with dark mortar.
pub fn cobblestone(size: u32, cells: u32, seed: u64) -> Image {
    let mut rng = SeededRng::new(seed);
    let pts: Vec<(f32, f32, [f32; 3])> = (0..cells)
        .map(|_| {
            let x = unit(rng.next_u64()) * size as f32;
            let y = unit(rng.next_u64()) * size as f32;
            let tone = 0.55 + 0.35 * unit(rng.next_u64());
            let warm = 0.9 + 0.2 * unit(rng.next_u64());
            (x, y, [tone * warm, tone, tone * (2.0 - warm) * 0.85])
        })
        .collect();
    let mut img = Image::new(size, size, 3);
    let s = size as f32;
    for y in 0..size {
        for x in 0..size {
            let (mut d1, mut d2, mut col) = (f32::MAX, f32::MAX, [0f32; 3]);
            for &(px, py, c) in &pts {
                let mut dx = (x as f32 + 0.5 - px).abs();
                let mut dy = (y as f32 + 0.5 - py).abs();
                dx = dx.min(s - dx);
                dy = dy.min(s - dy);
                let d = (dx * dx + dy * dy).sqrt();
                if d < d1 {
                    d2 = d1;
                    d1 = d;
                    col = c;
                } else if d < d2 {
                    d2 = d;
                }
            }
            let edge = ((d2 - d1) / 3.0).clamp(0.0, 1.0); // 0 at the mortar line
            let shade = 0.25 + 0.75 * edge.sqrt();
            let grain = 0.92 + 0.08 * unit(mix64(seed ^ ((y as u64) << 32 | x as u64)));
            let p = &mut img.pixels[((y * size + x) * 3) as usize..][..3];
            for k in 0..3 {
                p[k] = (255.0 * col[k] * shade * grain).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    img
}

/// Periodic value noise with `octaves` octaves, in [0, 1].
fn periodic_noise(x: f32, y: f32, period: u32, octaves: u32, seed: u64) -> f32 {
    let mut total = 0.0;
    let mut amp = 0.5;
    let mut norm = 0.0;
    for o in 0..octaves {
        let cells = 4u32 << o;
        let fx = x / period as f32 * cells as f32;
        let fy = y / period as f32 * cells as f32;
        let (ix, iy) = (fx.floor() as i64, fy.floor() as i64);
        let (tx, ty) = (fx - ix as f32, fy - iy as f32);
        let corner = |cx: i64, cy: i64| {
            let cx = cx.rem_euclid(cells as i64) as u64;
            let cy = cy.rem_euclid(cells as i64) as u64;
            unit(mix64(seed ^ (o as u64) << 56 ^ cy << 28 ^ cx))
        };
        let sx = tx * tx * (3.0 - 2.0 * tx);
        let sy = ty * ty * (3.0 - 2.0 * ty);
        let a = corner(ix, iy) + (corner(ix + 1, iy) - corner(ix, iy)) * sx;
        let b = corner(ix, iy + 1) + (corner(ix + 1, iy + 1) - corner(ix, iy + 1)) * sx;
        total += amp * (a + (b - a) * sy);
        norm += amp;
        amp *= 0.5;
    }
    total / norm
}

/// A veined marble: sine of a noise-warped diagonal, tileable.
pub fn marble(size: u32, seed: u64) -> Image {
    let mut img = Image::new(size, size, 3);
    for y in 0..size {
        for x in 0..size {
            let n = periodic_noise(x as f32, y as f32, size, 5, seed);
            let t = (x + y) as f32 / size as f32 * std::f32::consts::TAU * 2.0 + 9.0 * n;
            let v = (0.5 + 0.5 * t.sin()).powf(0.35);
            let p = &mut img.pixels[((y * size + x) * 3) as usize..][..3];
            p[0] = (70.0 + 175.0 * v) as u8;
            p[1] = (60.0 + 170.0 * v) as u8;
            p[2] = (55.0 + 150.0 * v) as u8;
        }
    }
    img
}

/// Red discs on a blue ground, with gentle shading and grain in each, tileable; and the mask
/// of the discs (255 inside, 0 outside, one channel): a two-region exemplar whose regions have
/// clearly different colours. `count` discs of radius `radius` pixels at seeded positions.
pub fn discs(size: u32, count: u32, radius: f32, seed: u64) -> (Image, Image) {
    let mut rng = SeededRng::new(seed);
    let centres: Vec<(f32, f32)> = (0..count)
        .map(|_| {
            (
                unit(rng.next_u64()) * size as f32,
                unit(rng.next_u64()) * size as f32,
            )
        })
        .collect();
    let (mut img, mut mask) = (Image::new(size, size, 3), Image::new(size, size, 1));
    let s = size as f32;
    for y in 0..size {
        for x in 0..size {
            let mut nearest = f32::MAX;
            for &(cx, cy) in &centres {
                let dx = (x as f32 + 0.5 - cx).abs();
                let dy = (y as f32 + 0.5 - cy).abs();
                let (dx, dy) = (dx.min(s - dx), dy.min(s - dy));
                nearest = nearest.min((dx * dx + dy * dy).sqrt() / radius);
            }
            let grain = unit(mix64(seed ^ ((y as u64) << 32 | x as u64))) - 0.5;
            let i = (y * size + x) as usize;
            let rgb = if nearest < 1.0 {
                mask.pixels[i] = 255;
                let shade = 1.0 - 0.25 * nearest * nearest;
                [230.0 * shade + 16.0 * grain, 40.0 + 10.0 * grain, 30.0]
            } else {
                let wave = (y as f32 / s * std::f32::consts::TAU).sin();
                [
                    30.0,
                    60.0 + 12.0 * wave + 10.0 * grain,
                    200.0 + 16.0 * grain,
                ]
            };
            for (o, v) in img.pixels[i * 3..i * 3 + 3].iter_mut().zip(rgb) {
                *o = v.round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    (img, mask)
}

/// Straight stripes of period `period` pixels along x, gray.
pub fn stripes(size: u32, period: u32) -> Image {
    let mut img = Image::new(size, size, 1);
    for y in 0..size {
        for x in 0..size {
            let phase = (x % period) as f32 / period as f32;
            img.pixels[(y * size + x) as usize] =
                (128.0 + 100.0 * (phase * std::f32::consts::TAU).sin()).round() as u8;
        }
    }
    img
}

/// A periodic 3D Voronoi texture (cells of varied colour, dark borders): a solid whose slices in
/// every direction are new pieces of the same texture. Test control for the evaluation: its
/// z = 0 slice is an exemplar that its other slices should match about as well as unseen texture.
pub fn cells_3d(size: u32, cells: u32, seed: u64) -> crate::volume::Volume {
    let mut rng = SeededRng::new(seed);
    let pts: Vec<([f32; 3], [f32; 3])> = (0..cells)
        .map(|_| {
            let p = [0, 1, 2].map(|_| unit(rng.next_u64()) * size as f32);
            // A four-colour palette, as in many stone textures.
            const PALETTE: [[f32; 3]; 4] = [
                [0.85, 0.7, 0.5],
                [0.55, 0.6, 0.65],
                [0.75, 0.75, 0.7],
                [0.5, 0.4, 0.35],
            ];
            (p, PALETTE[rng.below(4) as usize])
        })
        .collect();
    let s = size as f32;
    let mut v = crate::volume::Volume::new(size, size, size, 3);
    for z in 0..size {
        for y in 0..size {
            for x in 0..size {
                let (mut d1, mut d2, mut col) = (f32::MAX, f32::MAX, [0f32; 3]);
                for (p, c) in &pts {
                    let mut d = 0f32;
                    for (k, q) in [x, y, z].iter().enumerate() {
                        let a = (*q as f32 + 0.5 - p[k]).abs();
                        let a = a.min(s - a);
                        d += a * a;
                    }
                    let d = d.sqrt();
                    if d < d1 {
                        d2 = d1;
                        d1 = d;
                        col = *c;
                    } else if d < d2 {
                        d2 = d;
                    }
                }
                let shade = 0.2 + 0.8 * ((d2 - d1) / 2.5).clamp(0.0, 1.0).sqrt();
                let out = v.at_mut(x, y, z);
                for k in 0..3 {
                    out[k] = (255.0 * col[k] * shade).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
    v
}
