//! k-coherent 2D candidates (Ashikhmin 2001; Tong et al. 2002): for each exemplar pixel, itself
//! followed by the k-1 pixels whose projected neighbourhoods are nearest, spread out so they are
//! not just its immediate neighbours (Chebyshev distance >= MIN_SPACING from the pixel and from
//! each other).

use super::frame::pack;
use crate::exemplar::Border;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZeroUsize;

/// Minimum Chebyshev distance between a pixel and its candidates, and among candidates.
pub const MIN_SPACING: u32 = 3;
/// Nearest neighbours fetched per pixel before spacing them out.
const POOL: usize = 32;

fn chebyshev(a: u32, b: u32, w: u32, h: u32, border: Border) -> u32 {
    let (ax, ay, bx, by) = (a % w, a / w, b % w, b / w);
    let (mut dx, mut dy) = (ax.abs_diff(bx), ay.abs_diff(by));
    if border == Border::Wrap {
        dx = dx.min(w - dx);
        dy = dy.min(h - dy);
    }
    dx.max(dy)
}

/// `k` packed coordinates per pixel, row-major. `features` holds `dims` bytes per pixel.
pub fn candidates(
    features: &[u8],
    dims: usize,
    w: u32,
    h: u32,
    border: Border,
    k: usize,
) -> Vec<u32> {
    match dims {
        8 => with_dims::<8>(features, w, h, border, k),
        12 => with_dims::<12>(features, w, h, border, k),
        d => panic!("unsupported feature dims {d}"),
    }
}

fn with_dims<const D: usize>(
    features: &[u8],
    w: u32,
    h: u32,
    border: Border,
    k: usize,
) -> Vec<u32> {
    let points: Vec<[f32; D]> = features
        .chunks_exact(D)
        .map(|f| std::array::from_fn(|i| f[i] as f32))
        .collect();
    let tree: ImmutableKdTree<f32, D> = ImmutableKdTree::new_from_slice(&points).expect("tree");
    let pool = POOL.min(points.len());
    points
        .par_iter()
        .enumerate()
        .flat_map_iter(|(p, q)| {
            let p = p as u32;
            let mut found: Vec<(f32, u32)> = tree
                .query(q)
                .nearest_n::<SquaredEuclidean<f32>>(NonZeroUsize::new(pool).unwrap())
                .execute()
                .into_iter()
                .map(|r| (r.distance, r.item))
                .collect();
            found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let mut chosen = vec![p];
            for &(_, c) in &found {
                if chosen.len() == k {
                    break;
                }
                if chosen
                    .iter()
                    .all(|&o| chebyshev(o, c, w, h, border) >= MIN_SPACING)
                {
                    chosen.push(c);
                }
            }
            // Too few well-spaced matches (tiny levels): take the nearest others in order.
            for &(_, c) in &found {
                if chosen.len() == k {
                    break;
                }
                if !chosen.contains(&c) {
                    chosen.push(c);
                }
            }
            while chosen.len() < k {
                chosen.push(p);
            }
            chosen.into_iter().map(move |c| pack(c % w, c / w))
        })
        .collect()
}
