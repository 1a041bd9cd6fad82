//! A box delivered in slabs along z: each group's colours (and triples) placed into the slab of
//! the box it belongs to, one slab held at a time, or all of them joined into one volume.

use super::request::Job;
use super::*;

/// Slabs of one volume (see [`Slab`]) joined back into the whole volume and its triples.
pub(super) struct SlabsJoined {
    volume: Volume,
    triples: Vec<u32>,
}

impl SlabsJoined {
    pub(super) fn new(size: [u32; 3], channels: u32, want_triples: bool) -> SlabsJoined {
        let voxels = size.iter().map(|&d| d as usize).product::<usize>();
        let mut volume = Volume::new(size[0], size[1], 0, channels);
        volume.data.reserve(voxels * channels as usize);
        let triples = Vec::with_capacity(if want_triples { voxels * 3 } else { 0 });
        SlabsJoined { volume, triples }
    }

    /// The next slab along z.
    pub(super) fn push(&mut self, slab: Slab) -> Result<()> {
        self.volume.data.extend_from_slice(&slab.volume.data);
        self.volume.nz += slab.volume.nz;
        self.triples.extend_from_slice(slab.triples);
        Ok(())
    }

    pub(super) fn finish(self) -> (Volume, Vec<u32>) {
        (self.volume, self.triples)
    }
}

/// Consecutive z slices of a synthesized box (see `Synthesizer::synthesize_slabs`).
pub struct Slab<'a> {
    /// First slice's z, relative to the box.
    pub z0: u32,
    /// The slices: the box's x and y extents, `volume.nz` slices.
    pub volume: &'a Volume,
    /// Their triples (3 packed coordinates per voxel, x fastest) when asked for, else empty.
    pub triples: &'a [u32],
}

impl Synthesizer {
    /// [`Self::synthesize_slabs`] of the infinite solid ([`Periodic::No`]) or of a periodic one
    /// ([`Periodic::Unwrapped`]).
    /// `job.exact` is set to `out` here.
    pub(super) fn synthesize_slabs_of(
        &mut self,
        out: Box3,
        job: Job,
        mut sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        let want_triples = job.want_triples;
        let size = out.size();
        let channels = self.color_channels() as usize;
        let mut all = bricks::bricks_of_box(out);
        bricks::normalize(&mut all);
        // The slab being filled: its z range in the box, its voxels and triples.
        let mut pending: Option<(std::ops::Range<i32>, Volume, Vec<u32>)> = None;
        let mut flush =
            |pending: &mut Option<(std::ops::Range<i32>, Volume, Vec<u32>)>| match pending.take() {
                Some((z, volume, triples)) => sink(Slab {
                    z0: (z.start - out.lo[2]) as u32,
                    volume: &volume,
                    triples: &triples,
                }),
                None => Ok(()),
            };
        // Groups come z-major (see `groups`): a group starting above the slab begins the next.
        let job = Job {
            exact: Some(out),
            ..job
        };
        self.for_each_group(&all, job, |group, colors, group_triples| {
            let bz = group.iter().map(|b| b[2]).fold(i32::MAX, i32::min);
            let bz_end = group.iter().map(|b| b[2]).fold(i32::MIN, i32::max) + 1;
            let z = (bz * bricks::BRICK).max(out.lo[2])..(bz_end * bricks::BRICK).min(out.hi[2]);
            if pending
                .as_ref()
                .is_some_and(|(range, ..)| z.start >= range.end)
            {
                flush(&mut pending)?;
            }
            let (range, slab, slab_triples) = pending.get_or_insert_with(|| {
                let depth = (z.end - z.start) as u32;
                let voxels = size[0] as usize * size[1] as usize * depth as usize;
                (
                    z.clone(),
                    Volume::new(size[0], size[1], depth, channels as u32),
                    vec![0; if want_triples { voxels * 3 } else { 0 }],
                )
            });
            debug_assert!(z.start >= range.start && z.end <= range.end);
            let timer = std::time::Instant::now();
            place_group(
                group,
                colors,
                group_triples,
                out,
                range.start,
                slab,
                want_triples.then_some(slab_triples),
            );
            tracing::debug!("group placed in its slab in {:.1} ms", ms(timer));
            Ok(())
        })?;
        flush(&mut pending)
    }
}

/// Copy a group's colours (64 per brick, `group` order) and, when given, triples into the slab
/// of box `out` whose first z slice is `slab_z0`: the parts of the bricks inside the box. Brick
/// layers (4 z slices) are disjoint parts of the slab, filled in parallel.
fn place_group(
    group: &[Brick],
    colors: &[u32],
    group_triples: &[u32],
    out: Box3,
    slab_z0: i32,
    slab: &mut Volume,
    slab_triples: Option<&mut Vec<u32>>,
) {
    let channels = slab.channels as usize;
    let (sx, sy) = (slab.nx as usize, slab.ny as usize);
    let slice = sx * sy;
    let slab_z1 = slab_z0 + slab.nz as i32;
    // The group's bricks by layer: (brick z, index in the group), z ascending.
    let mut order: Vec<(i32, usize)> = group.iter().enumerate().map(|(j, b)| (b[2], j)).collect();
    order.sort_unstable();
    // Each layer's slices within the slab, then its part of the colours and triples.
    let mut layers = Vec::new();
    let (mut data, mut triples) = (
        &mut slab.data[..],
        slab_triples.map_or(&mut [][..], |t| &mut t[..]),
    );
    let mut consumed = slab_z0;
    for run in order.chunk_by(|a, b| a.0 == b.0) {
        let bz = run[0].0;
        let z0 = (bz * bricks::BRICK).max(out.lo[2]).max(slab_z0);
        let z1 = ((bz + 1) * bricks::BRICK).min(out.hi[2]).min(slab_z1);
        if z0 >= z1 {
            continue;
        }
        let skip = (z0 - consumed) as usize * slice;
        let take = (z1 - z0) as usize * slice;
        let rest = std::mem::take(&mut data);
        let (layer, rest) = rest[skip * channels..].split_at_mut(take * channels);
        data = rest;
        let (layer_triples, rest_triples) = if triples.is_empty() {
            (&mut [][..], &mut [][..])
        } else {
            let rest = std::mem::take(&mut triples);
            rest[skip * 3..].split_at_mut(take * 3)
        };
        triples = rest_triples;
        consumed = z1;
        layers.push((z0, z1, run, layer, layer_triples));
    }
    layers
        .into_par_iter()
        .for_each(|(z0, z1, run, layer, layer_triples)| {
            let with_triples = !layer_triples.is_empty();
            for &(_, j) in run {
                // The brick clipped to the box and to the layer: rows of consecutive voxels
                // along x, copied whole (a brick inside the box is 16 rows of 4).
                let lo = group[j].map(|v| v * bricks::BRICK);
                let from = [lo[0].max(out.lo[0]), lo[1].max(out.lo[1]), lo[2].max(z0)];
                let end = [out.hi[0], out.hi[1], z1];
                let to = [0, 1, 2].map(|i| (lo[i] + bricks::BRICK).min(end[i]));
                let run_len = (to[0] - from[0]).max(0) as usize;
                for z in from[2]..to[2] {
                    for y in from[1]..to[1] {
                        let first = ((z - z0) as usize * sy + (y - out.lo[1]) as usize) * sx
                            + (from[0] - out.lo[0]) as usize;
                        let src = j * 64
                            + ((z - lo[2]) * 16 + (y - lo[1]) * 4 + (from[0] - lo[0])) as usize;
                        let dst = &mut layer[first * channels..(first + run_len) * channels];
                        write_colors(dst, &colors[src..src + run_len], channels);
                        if with_triples {
                            layer_triples[first * 3..(first + run_len) * 3]
                                .copy_from_slice(&group_triples[src * 3..(src + run_len) * 3]);
                        }
                    }
                }
            }
        });
}

/// Packed colours (little-endian bytes) written as `channels` bytes each. The common channel
/// counts get fixed-size copies: with the count only known at run time each voxel's copy is a
/// `memcpy` call (which made place_group 12% of a warm 256^2 cut's main-thread CPU on the 2-core
/// Intel Xeon development machine).
fn write_colors(dst: &mut [u8], colors: &[u32], channels: usize) {
    fn each<const N: usize>(dst: &mut [u8], colors: &[u32]) {
        for (pixel, color) in dst.chunks_exact_mut(N).zip(colors) {
            let bytes: [u8; 4] = color.to_le_bytes();
            pixel.copy_from_slice(&bytes[..N]);
        }
    }
    match channels {
        1 => each::<1>(dst, colors),
        2 => each::<2>(dst, colors),
        3 => each::<3>(dst, colors),
        4 => each::<4>(dst, colors),
        _ => unreachable!("{channels} colour channels"),
    }
}
