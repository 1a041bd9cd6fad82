//! Colour-consistency candidates (paper 4.1): for every pixel p of exemplar E_a, the S strips of
//! E_{a+1} and of E_{a+2} nearest to p's crossing strips (k-d tree on PCA-reduced strips), all
//! S^2 triples scored by the exact crossbar error CB on the full 8-bit strips, the best kept.
//!
//! Ties are broken by (CB, index of the E_{a+1} pixel, index of the E_{a+2} pixel): cyclic, so the
//! shared single-image path and three identical images give identical sets (see `frame`).

use super::frame::{next, pack};
use super::neighbourhood::{all_strips, h_strip, v_strip};
use crate::exemplar::{Border, Image};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZeroUsize;

/// Dimensions of the reduced strip vectors in the k-d trees.
pub const STRIP_TREE_DIMS: usize = 8;

/// A triple ranked by its crossbar error. `coords[a]` is the pixel itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RankedTriple {
    pub cb: u32,
    /// Pixel indices (y * width + x) in E_{a+1} and E_{a+2}.
    pub next1: u32,
    pub next2: u32,
}

/// Strips of one exemplar at one level: raw bytes for exact CB, reduced floats for the trees.
pub struct Strips {
    pub len: usize,
    pub h: Vec<u8>,
    pub v: Vec<u8>,
    pub h_reduced: Vec<[f32; STRIP_TREE_DIMS]>,
    pub v_reduced: Vec<[f32; STRIP_TREE_DIMS]>,
}

impl Strips {
    pub fn h_of(&self, i: usize) -> &[u8] {
        &self.h[i * self.len..(i + 1) * self.len]
    }
    pub fn v_of(&self, i: usize) -> &[u8] {
        &self.v[i * self.len..(i + 1) * self.len]
    }
}

/// A linear map fitted on strips (PCA) to reduce them for the k-d trees.
struct StripReducer {
    mean: Vec<f32>,
    rows: Vec<Vec<f32>>,
}

impl StripReducer {
    fn fit(all: &[&[u8]], len: usize) -> StripReducer {
        let flat: Vec<u8> = all.iter().flat_map(|s| s.iter().copied()).collect();
        let keep = STRIP_TREE_DIMS.min(len);
        let pca = super::pca::fit(&flat, len, keep, &vec![1.0; len], 1 << 16)
            .expect("strips are never empty");
        // Undo the fixed-point scale: we only need an orthogonal projection up to a common factor.
        let f = (1u64 << pca.shift) as f32;
        let rows = (0..keep)
            .map(|j| {
                pca.weights[j * len..(j + 1) * len]
                    .iter()
                    .map(|&w| w as f32 / f)
                    .collect()
            })
            .collect();
        StripReducer {
            mean: pca.mean.iter().map(|&m| m as f32).collect(),
            rows,
        }
    }
    fn reduce(&self, s: &[u8]) -> [f32; STRIP_TREE_DIMS] {
        let mut out = [0f32; STRIP_TREE_DIMS];
        for (o, row) in out.iter_mut().zip(&self.rows) {
            *o = s
                .iter()
                .zip(row)
                .zip(&self.mean)
                .map(|((&x, &w), &m)| (x as f32 - m) * w)
                .sum();
        }
        out
    }
}

/// Build the strips of each distinct exemplar, with one reducer fitted on all of them so reduced
/// strips of different exemplars are comparable.
pub fn build_strips(images: &[&Image], border: Border) -> Vec<Strips> {
    let len = 5 * images[0].channels as usize;
    let raw: Vec<(Vec<u8>, Vec<u8>)> = images
        .iter()
        .map(|img| {
            (
                all_strips(img, border, h_strip),
                all_strips(img, border, v_strip),
            )
        })
        .collect();
    let mut sample: Vec<&[u8]> = Vec::new();
    for (h, v) in &raw {
        sample.extend(h.chunks_exact(len));
        sample.extend(v.chunks_exact(len));
    }
    let reducer = StripReducer::fit(&sample, len);
    raw.into_iter()
        .map(|(h, v)| {
            let h_reduced = h.par_chunks(len).map(|s| reducer.reduce(s)).collect();
            let v_reduced = v.par_chunks(len).map(|s| reducer.reduce(s)).collect();
            Strips {
                len,
                h,
                v,
                h_reduced,
                v_reduced,
            }
        })
        .collect()
}

/// A k-d tree over the first K reduced dimensions (K = 5 for gray strips, whose reduced vectors
/// have only 5 meaningful dimensions: constant padded ones would make the tree degenerate).
enum Tree {
    Five(ImmutableKdTree<f32, 5>),
    Eight(ImmutableKdTree<f32, STRIP_TREE_DIMS>),
}

impl Tree {
    fn new(points: &[[f32; STRIP_TREE_DIMS]], strip_len: usize) -> Tree {
        if strip_len < STRIP_TREE_DIMS {
            let p5: Vec<[f32; 5]> = points
                .iter()
                .map(|p| std::array::from_fn(|i| p[i]))
                .collect();
            Tree::Five(ImmutableKdTree::new_from_slice(&p5).expect("tree"))
        } else {
            Tree::Eight(ImmutableKdTree::new_from_slice(points).expect("tree"))
        }
    }
}

fn nearest(tree: &Tree, q: &[f32; STRIP_TREE_DIMS], n: usize) -> Vec<u32> {
    let n = NonZeroUsize::new(n).unwrap();
    let raw = match tree {
        Tree::Five(t) => {
            let q5: [f32; 5] = std::array::from_fn(|i| q[i]);
            t.query(&q5).nearest_n::<SquaredEuclidean<f32>>(n).execute()
        }
        Tree::Eight(t) => t.query(q).nearest_n::<SquaredEuclidean<f32>>(n).execute(),
    };
    let mut found: Vec<(f32, u32)> = raw.into_iter().map(|r| (r.distance, r.item)).collect();
    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    found.into_iter().map(|(_, i)| i).collect()
}

#[inline]
fn ssd(a: &[u8], b: &[u8]) -> u32 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| (x as i32 - y as i32).pow(2) as u32)
        .sum()
}

/// CB of the triple (p in E_a, q in E_{a+1}, r in E_{a+2}), strips indexed by exemplar.
pub fn crossbar_error(strips: [&Strips; 3], p: usize, q: usize, r: usize) -> u32 {
    ssd(strips[0].v_of(p), strips[1].h_of(q))
        + ssd(strips[1].v_of(q), strips[2].h_of(r))
        + ssd(strips[2].v_of(r), strips[0].h_of(p))
}

/// The best `keep` triples of every pixel of E_a, from `strips_per_axis` (S) strips per axis.
/// `strips[i]` are the strips of E_{a+i} (i = 0, 1, 2).
pub fn candidates(
    strips: [&Strips; 3],
    strips_per_axis: usize,
    keep: usize,
) -> Vec<Vec<RankedTriple>> {
    let count = |s: &Strips| s.h.len() / s.len;
    let (n0, n1, n2) = (count(strips[0]), count(strips[1]), count(strips[2]));
    let h_tree1 = Tree::new(&strips[1].h_reduced, strips[1].len);
    let v_tree2 = Tree::new(&strips[2].v_reduced, strips[2].len);
    let s1 = strips_per_axis.min(n1);
    let s2 = strips_per_axis.min(n2);
    (0..n0)
        .into_par_iter()
        .map_init(Vec::new, |pairs: &mut Vec<(u32, u32, u32)>, p| {
            let qs = nearest(&h_tree1, &strips[0].v_reduced[p], s1);
            let rs = nearest(&v_tree2, &strips[0].h_reduced[p], s2);
            pairs.clear();
            let (vp, hp) = (strips[0].v_of(p), strips[0].h_of(p));
            let d_r: Vec<u32> = rs
                .iter()
                .map(|&r| ssd(strips[2].v_of(r as usize), hp))
                .collect();
            for &q in &qs {
                let d_q = ssd(vp, strips[1].h_of(q as usize));
                let vq = strips[1].v_of(q as usize);
                for (&r, &dr) in rs.iter().zip(&d_r) {
                    let cb = d_q + ssd(vq, strips[2].h_of(r as usize)) + dr;
                    pairs.push((cb, q, r));
                }
            }
            let k = keep.min(pairs.len());
            if k < pairs.len() {
                pairs.select_nth_unstable(k - 1);
                pairs.truncate(k);
            }
            pairs.sort_unstable();
            pairs
                .iter()
                .map(|&(cb, next1, next2)| RankedTriple { cb, next1, next2 })
                .collect()
        })
        .collect()
}

/// A ranked triple of pixel `p` of E_a as packed coordinates in canonical (Ex, Ey, Ez) order.
pub fn to_triple(a: usize, p: usize, t: &RankedTriple, widths: [u32; 3]) -> [u32; 3] {
    let mut out = [0u32; 3];
    let coord = |i: usize, w: u32| pack(i as u32 % w, i as u32 / w);
    out[a] = coord(p, widths[a]);
    out[next(a)] = coord(t.next1 as usize, widths[next(a)]);
    out[next(next(a))] = coord(t.next2 as usize, widths[next(next(a))]);
    out
}
