//! Cross-sections of an LST model (paper 5.1.1) by marching tetrahedra: each tet the plane
//! crosses gives a triangle or a quad whose corners carry the tet's barycentric coordinates; the
//! polygons are rasterized into the cut image and every pixel composites the tet's layers
//! ([`LstModel::shade`]). Only texture coordinates are interpolated: no synthesis.
//!
//! The image frame is [`crate::lazy::cut::CutSpec`]'s (same u, v axes as `solidsynth cut`), with
//! `spacing` in model units per pixel. Pixels off the model are transparent.

use super::model::LstModel;
use crate::error::Result;
use crate::lazy::cut::CutSpec;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// A cross-section triangle in pixel coordinates, with the barycentric coordinates of its tet at
/// its corners.
struct Piece {
    tet: u32,
    xy: [DVec2; 3],
    bary: [[f32; 4]; 3],
}

/// Rows per parallel band.
const BAND: u32 = 16;

/// The cut image, RGBA8 row-major (row 0 first).
pub fn cut(model: &LstModel, spec: &CutSpec) -> Result<image::RgbaImage> {
    let (u, v, n) = spec.frame()?;
    let o = DVec3::from_array(spec.origin);
    let half = spec.size as f64 / 2.0;
    let to_pixel = |p: DVec3| {
        let d = p - o;
        DVec2::new(
            d.dot(u) / spec.spacing + half,
            d.dot(v) / spec.spacing + half,
        )
    };
    let pieces = march(model, o, n, &to_pixel);

    let size = spec.size;
    let bands = size.div_ceil(BAND);
    // Bucket the pieces by the bands their rows touch, so bands rasterize in parallel.
    let mut by_band: Vec<Vec<u32>> = vec![Vec::new(); bands as usize];
    for (i, p) in pieces.iter().enumerate() {
        let lo = p.xy.iter().map(|q| q.y).fold(f64::INFINITY, f64::min);
        let hi = p.xy.iter().map(|q| q.y).fold(f64::NEG_INFINITY, f64::max);
        if hi < 0.0 || lo > size as f64 {
            continue;
        }
        let first = (lo.max(0.0) as u32 / BAND).min(bands - 1);
        let last = (hi.min(size as f64 - 1.0).max(0.0) as u32 / BAND).min(bands - 1);
        for b in first..=last {
            by_band[b as usize].push(i as u32);
        }
    }
    let mut pixels = vec![0u8; size as usize * size as usize * 4];
    pixels
        .par_chunks_mut((BAND * size * 4) as usize)
        .enumerate()
        .for_each(|(band, rows)| {
            let y0 = band as u32 * BAND;
            let y1 = (y0 + BAND).min(size);
            for &i in &by_band[band] {
                raster(model, &pieces[i as usize], y0, y1, size, rows);
            }
        });
    Ok(image::RgbaImage::from_raw(size, size, pixels).expect("buffer size matches"))
}

/// The cross-section pieces: for each tet with vertices on both sides of the plane, the points
/// where its edges cross it (3 or 4), as one or two triangles.
fn march(
    model: &LstModel,
    o: DVec3,
    n: DVec3,
    to_pixel: &(dyn Fn(DVec3) -> DVec2 + Sync),
) -> Vec<Piece> {
    let mesh = &model.mesh;
    let dist: Vec<f64> = mesh.vertices.iter().map(|p| (*p - o).dot(n)).collect();
    (0..mesh.tets.len())
        .into_par_iter()
        .flat_map_iter(|t| {
            let tet = mesh.tets[t];
            let d = tet.map(|v| dist[v as usize]);
            let mut points: Vec<(DVec2, [f32; 4])> = Vec::with_capacity(4);
            if d.iter().all(|&x| x > 0.0) || d.iter().all(|&x| x <= 0.0) {
                return Vec::new().into_iter();
            }
            for a in 0..4 {
                for b in a + 1..4 {
                    if (d[a] > 0.0) != (d[b] > 0.0) {
                        let s = d[a] / (d[a] - d[b]);
                        let p =
                            mesh.vertices[tet[a] as usize].lerp(mesh.vertices[tet[b] as usize], s);
                        let mut bary = [0.0f32; 4];
                        bary[a] = (1.0 - s) as f32;
                        bary[b] = s as f32;
                        points.push((to_pixel(p), bary));
                    }
                }
            }
            // A quad's four crossing points: order them around their centre before fanning.
            if points.len() == 4 {
                let c = points.iter().map(|p| p.0).sum::<DVec2>() / 4.0;
                points.sort_by(|a, b| {
                    let (da, db) = (a.0 - c, b.0 - c);
                    da.y.atan2(da.x).total_cmp(&db.y.atan2(db.x))
                });
            }
            let mut out = Vec::with_capacity(2);
            for k in 1..points.len() - 1 {
                out.push(Piece {
                    tet: t as u32,
                    xy: [points[0].0, points[k].0, points[k + 1].0],
                    bary: [points[0].1, points[k].1, points[k + 1].1],
                });
            }
            out.into_iter()
        })
        .collect()
}

/// Rasterize one piece into rows [y0, y1) (`rows` holds exactly those rows): every pixel whose
/// centre lies in the triangle takes the composited colour of its point.
fn raster(model: &LstModel, p: &Piece, y0: u32, y1: u32, size: u32, rows: &mut [u8]) {
    let [a, b, c] = p.xy;
    let area = (b - a).perp_dot(c - a);
    if area.abs() < 1e-12 {
        return;
    }
    let lo = a.min(b).min(c);
    let hi = a.max(b).max(c);
    let xs = (lo.x - 0.5).ceil().max(0.0) as u32;
    let xe = ((hi.x - 0.5).floor()).min(size as f64 - 1.0);
    let ys = ((lo.y - 0.5).ceil().max(y0 as f64)) as u32;
    let ye = ((hi.y - 0.5).floor()).min(y1 as f64 - 1.0);
    if xe < 0.0 || ye < 0.0 {
        return;
    }
    let (xe, ye) = (xe as u32, ye as u32);
    for y in ys..=ye {
        for x in xs..=xe {
            let q = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let wa = (b - q).perp_dot(c - q) / area;
            let wb = (c - q).perp_dot(a - q) / area;
            let wc = 1.0 - wa - wb;
            const EPS: f64 = -1e-9;
            if wa < EPS || wb < EPS || wc < EPS {
                continue;
            }
            let mut bary = [0.0f32; 4];
            for k in 0..4 {
                bary[k] = (wa as f32) * p.bary[0][k]
                    + (wb as f32) * p.bary[1][k]
                    + (wc as f32) * p.bary[2][k];
            }
            let rgba = model.shade(p.tet as usize, bary);
            let o = (((y - y0) * size + x) * 4) as usize;
            for ch in 0..3 {
                rows[o + ch] = rgba[ch].round().clamp(0.0, 255.0) as u8;
            }
            rows[o + 3] = 255;
        }
    }
}
