//! An inverted-file partition of the candidate patches' PCA projections for the approximate
//! nearest-patch search (the paper uses an approximate search, ANN, at this step: 4.2.1). The
//! candidates are split into lists by k-means; a query scans only the lists whose centres lie
//! nearest to it. Deterministic: fixed initial centres, a fixed number of Lloyd iterations, sums
//! in index order.

use super::pca::KEPT;
use rayon::prelude::*;

/// Lloyd iterations of the partition.
const ITERATIONS: usize = 8;

/// Squared distance of two projections, summed in dimension order.
#[inline]
pub fn distance(a: &[f32; KEPT], b: &[f32; KEPT]) -> f32 {
    let mut d = 0.0;
    for j in 0..KEPT {
        let t = a[j] - b[j];
        d += t * t;
    }
    d
}

/// The list count for `n` candidates: about sqrt(n), a power of two, 1..=256.
pub fn list_count(n: usize) -> usize {
    ((n as f64).sqrt() as usize)
        .next_power_of_two()
        .clamp(1, 256)
}

/// Index of the centre nearest to `p` (ties: the lower index).
fn nearest_centre(p: &[f32; KEPT], centres: &[[f32; KEPT]]) -> u32 {
    let mut best = (f32::INFINITY, 0);
    for (j, c) in centres.iter().enumerate() {
        let d = distance(p, c);
        if d < best.0 {
            best = (d, j as u32);
        }
    }
    best.1
}

/// K-means of `points` into `lists` lists: every point's list and the list centres. The
/// initial centres are points picked by a golden-ratio sequence over the candidate order (a
/// regular stride would alias with the raster order of the candidates' exemplar positions);
/// an emptied list keeps its centre.
pub fn partition(points: &[[f32; KEPT]], lists: usize) -> (Vec<u32>, Vec<[f32; KEPT]>) {
    let lists = lists.clamp(1, points.len().max(1));
    const GOLDEN: f64 = 0.618_033_988_749_894_9;
    let mut centres: Vec<[f32; KEPT]> = (0..lists)
        .map(|j| {
            let t = (0.5 + j as f64 * GOLDEN).fract();
            points[((t * points.len() as f64) as usize).min(points.len() - 1)]
        })
        .collect();
    let mut labels = vec![0u32; points.len()];
    for _ in 0..ITERATIONS {
        labels = points
            .par_iter()
            .map(|p| nearest_centre(p, &centres))
            .collect();
        let mut sums = vec![[0f64; KEPT]; lists];
        let mut counts = vec![0usize; lists];
        for (p, &l) in points.iter().zip(&labels) {
            counts[l as usize] += 1;
            for (s, &v) in sums[l as usize].iter_mut().zip(p) {
                *s += v as f64;
            }
        }
        for j in 0..lists {
            if counts[j] > 0 {
                centres[j] = std::array::from_fn(|d| (sums[j][d] / counts[j] as f64) as f32);
            }
        }
    }
    let labels = points
        .par_iter()
        .map(|p| nearest_centre(p, &centres))
        .collect();
    (labels, centres)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partition_groups_separated_points() {
        // Two well-separated groups: each ends in lists of its own group only.
        let points: Vec<[f32; KEPT]> = (0..200)
            .map(|i| {
                let mut p = [0f32; KEPT];
                p[0] = if i % 2 == 0 { 100.0 } else { -100.0 };
                p[1] = (i % 17) as f32;
                p
            })
            .collect();
        let (labels, centres) = partition(&points, 4);
        assert_eq!(centres.len(), 4);
        for (i, p) in points.iter().enumerate() {
            let c = &centres[labels[i] as usize];
            assert_eq!(
                c[0].signum(),
                p[0].signum(),
                "point {i} in the other group's list"
            );
        }
        // Deterministic.
        assert_eq!(partition(&points, 4).0, labels);
    }
}
