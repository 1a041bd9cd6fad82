//! CPU reference of `wgsl/tricubic_eval.wgsl`: a gradient solid evaluated at the points of a
//! query, all channels per point, in f32 (the interpolant is derived in `gradient`).

use crate::gradient::GradientSolid;
use rayon::prelude::*;

/// Where to evaluate.
#[derive(Clone, Debug, PartialEq)]
pub enum Query {
    /// origin + i a + j b + k c for i < n[0], j < n[1], k < n[2] (i fastest): a volume with unit
    /// axes, or a slice of any orientation with n[2] = 1.
    Grid {
        origin: [f32; 3],
        a: [f32; 3],
        b: [f32; 3],
        c: [f32; 3],
        n: [u32; 3],
    },
    /// Explicit voxel-space points.
    Points(Vec<[f32; 3]>),
}

impl Query {
    /// The box [0, n)^3 at integer voxel positions.
    pub fn volume(n: [u32; 3]) -> Query {
        Query::Grid {
            origin: [0.0; 3],
            a: [1.0, 0.0, 0.0],
            b: [0.0, 1.0, 0.0],
            c: [0.0, 0.0, 1.0],
            n,
        }
    }

    pub fn len(&self) -> usize {
        match self {
            Query::Grid { n, .. } => n.iter().map(|&v| v as usize).product(),
            Query::Points(p) => p.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Point `idx`, computed in the shader's order of operations.
    pub fn point(&self, idx: usize) -> [f32; 3] {
        match self {
            Query::Grid { origin, a, b, c, n } => {
                let i = (idx % n[0] as usize) as f32;
                let j = ((idx / n[0] as usize) % n[1] as usize) as f32;
                let k = (idx / (n[0] as usize * n[1] as usize)) as f32;
                [0, 1, 2].map(|d| origin[d] + i * a[d] + j * b[d] + k * c[d])
            }
            Query::Points(p) => p[idx],
        }
    }
}

/// `channels` values per point of the query, in query order.
pub fn tricubic_eval(solid: &GradientSolid, query: &Query) -> Vec<f32> {
    let c = solid.channels as usize;
    let mut out = vec![0f32; query.len() * c];
    out.par_chunks_mut(c * 256)
        .enumerate()
        .for_each(|(chunk, dst)| {
            for (k, values) in dst.chunks_mut(c).enumerate() {
                solid.eval(query.point(chunk * 256 + k), values);
            }
        });
    out
}
