//! CPU reference of `wgsl/bucket_accumulate.wgsl`: buckets of matched patch samples per voxel
//! (gradient-solid synthesis, paper 4.2.5). Integer atomics, so the result is the same whatever
//! the order of the samples and the thread count.

use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

/// Per voxel and for each of its two dominant clusters: the sample count and the channel sums in
/// 8.8 fixed point (value << 8).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Buckets {
    pub counts: Vec<u32>,
    pub sums: Vec<u32>,
}

/// The two clusters with most samples (ties to the lower id; u32::MAX when none).
pub fn dominant(counts: &[u32]) -> [u32; 2] {
    let (mut first, mut second, mut n1, mut n2) = (u32::MAX, u32::MAX, 0u32, 0u32);
    for (c, &n) in counts.iter().enumerate() {
        if n > n1 {
            (second, n2) = (first, n1);
            (first, n1) = (c as u32, n);
        } else if n > n2 {
            (second, n2) = (c as u32, n);
        }
    }
    [first, second]
}

/// `samples`: per sample, voxel index, cluster id, `channels` values. Both passes.
pub fn bucket_accumulate(samples: &[u32], voxels: usize, clusters: u32, channels: u32) -> Buckets {
    let stride = 2 + channels as usize;
    let counts: Vec<AtomicU32> = (0..voxels * clusters as usize)
        .map(|_| AtomicU32::new(0))
        .collect();
    samples.par_chunks_exact(stride).for_each(|s| {
        if s[1] < clusters {
            counts[s[0] as usize * clusters as usize + s[1] as usize].fetch_add(1, Relaxed);
        }
    });
    let counts: Vec<u32> = counts.into_iter().map(|a| a.into_inner()).collect();
    let per = 1 + channels as usize;
    let sums: Vec<AtomicU32> = (0..voxels * 2 * per).map(|_| AtomicU32::new(0)).collect();
    samples.par_chunks_exact(stride).for_each(|s| {
        let (voxel, cluster) = (s[0] as usize, s[1]);
        if cluster >= clusters {
            return;
        }
        let d = dominant(&counts[voxel * clusters as usize..(voxel + 1) * clusters as usize]);
        let Some(slot) = d.iter().position(|&c| c == cluster) else {
            return;
        };
        let base = (voxel * 2 + slot) * per;
        sums[base].fetch_add(1, Relaxed);
        for c in 0..channels as usize {
            sums[base + 1 + c].fetch_add(s[2 + c].min(255) << 8, Relaxed);
        }
    });
    Buckets {
        counts,
        sums: sums.into_iter().map(|a| a.into_inner()).collect(),
    }
}
