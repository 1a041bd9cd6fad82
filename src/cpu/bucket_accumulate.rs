//! CPU reference of `wgsl/bucket_accumulate.wgsl`: buckets of matched patch samples per voxel
//! (gradient-solid synthesis, paper 4.2.5). Integer atomics, so the result is the same whatever
//! the order of the samples and the thread count.
//!
//! Also the CPU backend's optimized path, [`PackedSums`]: samples streamed straight into
//! per-(voxel, cluster) sums without the kernel's sample list; `gradient::synth::buckets`' tests hold
//! it to [`bucket_accumulate`], the plain mirror of the shader.

use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

pub use crate::contract::buckets::Buckets;

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

/// Per (voxel, cluster), the sample count and channel sums as the four 16-bit lanes of one u64
/// (the CPU backend's bucket sums; a sample is packed alike: 1, then its channel values, at
/// most 3). A channel lane could overflow past 257 samples of 255, so a slot whose count reaches
/// 256 is moved to a list of spilled sums and restarts at zero: the totals are exact.
#[derive(Clone)]
pub struct PackedSums {
    clusters: usize,
    acc: Vec<u64>,
    spills: Vec<(usize, u64)>,
}

impl PackedSums {
    const SPILL_AT: u16 = 256;
    /// Channels a packed sample holds besides its count.
    pub const CHANNELS: usize = 3;

    /// A sample of `values` (at most [`Self::CHANNELS`]) as lanes: 1, then each value.
    pub fn pack(values: &[u8]) -> u64 {
        debug_assert!(values.len() <= Self::CHANNELS);
        let lanes = values.iter().enumerate();
        lanes.fold(1, |word, (c, &v)| word | (v as u64) << (16 * (c + 1)))
    }

    pub fn new(voxels: usize, clusters: usize) -> PackedSums {
        PackedSums {
            clusters,
            acc: vec![0; voxels * clusters],
            spills: Vec::new(),
        }
    }

    /// Adds a sample of `cluster` (`word`: its packed count and values) to voxel `v`.
    #[inline(always)]
    pub fn add(&mut self, v: usize, (cluster, word): (u32, u64)) {
        let i = v * self.clusters + cluster as usize;
        let sum = self.acc[i] + word;
        if sum as u16 == Self::SPILL_AT {
            self.spills.push((i, sum));
            self.acc[i] = 0;
        } else {
            self.acc[i] = sum;
        }
    }

    /// The kernel's result: each voxel's two dominant clusters' counts and sums in 8.8 fixed
    /// point, and with `with_counts` every (voxel, cluster) count (only the region separation
    /// reads those; the packed path has no regions, so synthesis leaves them out).
    pub fn finish(self, channels: usize, with_counts: bool) -> Buckets {
        let (clusters, per) = (self.clusters, 1 + channels);
        let voxels = self.acc.len() / clusters;
        let lane = |word: u64, l: usize| ((word >> (16 * l)) & 0xFFFF) as u32;
        // Slot -> its unpacked lanes, for the few slots that spilled.
        let mut spilled: std::collections::BTreeMap<usize, [u32; 4]> = Default::default();
        for (i, word) in self.spills {
            let lanes = spilled.entry(i).or_default();
            for (l, lane_sum) in lanes.iter_mut().enumerate() {
                *lane_sum += lane(word, l);
            }
        }
        let acc = self.acc;
        let any_spilled = !spilled.is_empty();
        let unpacked = |i: usize, l: usize| {
            let spilled_lanes = if any_spilled {
                spilled.get(&i).map_or(0, |lanes| lanes[l])
            } else {
                0
            };
            lane(acc[i], l) + spilled_lanes
        };
        let counts: Vec<u32> = if with_counts {
            (0..acc.len()).map(|i| unpacked(i, 0)).collect()
        } else {
            Vec::new()
        };
        let mut sums = vec![0u32; voxels * 2 * per];
        let mut voxel_counts = vec![0u32; clusters];
        for (v, out) in sums.chunks_exact_mut(2 * per).enumerate() {
            let ids = if any_spilled {
                for (k, count) in voxel_counts.iter_mut().enumerate() {
                    *count = unpacked(v * clusters + k, 0);
                }
                dominant(&voxel_counts)
            } else {
                dominant_of_words(&acc[v * clusters..(v + 1) * clusters])
            };
            for (slot, &id) in ids.iter().enumerate() {
                if id != u32::MAX {
                    let i = v * clusters + id as usize;
                    out[slot * per] = unpacked(i, 0);
                    for l in 1..per {
                        // Raw value sums, scaled to 8.8 fixed point like the kernel's.
                        out[slot * per + l] = unpacked(i, l) << 8;
                    }
                }
            }
        }
        Buckets { counts, sums }
    }
}

/// [`dominant`] of the counts in the low lanes of packed `words` (none spilled): the two
/// clusters with most samples, ties to the lower id, `u32::MAX` for none. Two maxima of keys
/// (count, then the complement of the id) instead of a chain of compare-and-swaps whose
/// branches the random counts mispredict (that had cost a tenth of the synthesis).
#[inline(always)]
fn dominant_of_words(words: &[u64]) -> [u32; 2] {
    const ID_BITS: u32 = 8;
    const ID_MASK: u32 = (1 << ID_BITS) - 1;
    debug_assert!(words.len() <= 1 << ID_BITS);
    let key =
        |(k, &word): (usize, &u64)| ((word as u32 & 0xFFFF) << ID_BITS) | (ID_MASK - k as u32);
    let first = words.iter().enumerate().map(key).fold(0, u32::max);
    let second =
        words
            .iter()
            .enumerate()
            .map(key)
            .fold(0, |best, k| if k == first { best } else { best.max(k) });
    // A count of 0 is no cluster.
    let id = |key: u32| {
        if key >> ID_BITS == 0 {
            u32::MAX
        } else {
            ID_MASK - (key & ID_MASK)
        }
    };
    [id(first), id(second)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::hash::SeededRng;

    #[test]
    fn dominant_of_words_equals_the_kernels_choice() {
        let mut rng = SeededRng::new(5);
        for round in 0..2000 {
            let n = 1 + rng.below(32) as usize;
            // Few distinct counts (ties), zeros included; the other lanes hold sums.
            let counts: Vec<u32> = (0..n)
                .map(|_| rng.below(1 + (round % 7) as u64) as u32)
                .collect();
            let words: Vec<u64> = counts
                .iter()
                .map(|&c| c as u64 | (rng.below(1 << 40) << 16))
                .collect();
            assert_eq!(dominant_of_words(&words), dominant(&counts), "{counts:?}");
        }
    }

    /// The packed sums equal the plain mirror of the kernel, also for slots far past the
    /// 16-bit lanes' range (thousands of samples of 255 in one voxel and cluster).
    #[test]
    fn packed_sums_equal_the_kernel_reference_past_the_lanes_range() {
        let (voxels, clusters, channels) = (7usize, 5usize, 3usize);
        let mut rng = SeededRng::new(11);
        let mut below = |n: usize| rng.below(n as u64) as u32;
        let mut samples: Vec<[u32; 5]> = Vec::new();
        for _ in 0..20_000 {
            let v = below(voxels);
            // Voxel 0 gets one heavy cluster of saturated values, the rest are random.
            let (cluster, values) = if v == 0 && below(4) > 0 {
                (2, [255, 255, 254])
            } else {
                let c = below(clusters);
                (c, [below(256), below(256), below(256)])
            };
            samples.push([v, cluster, values[0], values[1], values[2]]);
        }
        let mut packed = PackedSums::new(voxels, clusters);
        for s in &samples {
            let values = [s[2], s[3], s[4]].map(|v| v as u8);
            packed.add(s[0] as usize, (s[1], PackedSums::pack(&values)));
        }
        assert!(packed.spills.len() > 10, "the test must spill");
        let flat: Vec<u32> = samples.iter().flatten().copied().collect();
        let want = bucket_accumulate(&flat, voxels, clusters as u32, channels as u32);
        let without_counts = packed.clone().finish(channels, false);
        assert!(without_counts.counts.is_empty());
        assert_eq!(without_counts.sums, want.sums);
        assert_eq!(packed.finish(channels, true), want);
        // And without any spill (the usual case, a path of its own): the first 300 samples.
        let few = &samples[..300];
        let mut packed = PackedSums::new(voxels, clusters);
        for s in few {
            let values = [s[2], s[3], s[4]].map(|v| v as u8);
            packed.add(s[0] as usize, (s[1], PackedSums::pack(&values)));
        }
        assert!(packed.spills.is_empty());
        let flat: Vec<u32> = few.iter().flatten().copied().collect();
        let want = bucket_accumulate(&flat, voxels, clusters as u32, channels as u32);
        assert_eq!(packed.finish(channels, true), want);
    }
}
