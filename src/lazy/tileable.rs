//! Tileable solids: a volume periodic with its own size along each axis, every level periodic
//! with its own period, synthesized in one piece (reads wrap) or, when too large, as a box of
//! the periodic solid in groups.

use super::group::{FirstLevel, GroupResult};
use super::request::{Job, Periodic};
use super::slabs::SlabsJoined;
use super::*;

impl Synthesizer {
    /// A tileable solid: the `n`^3 volume of a solid periodic with period `n` along each axis
    /// (every level periodic with its own size), so copies of it tile space seamlessly. Its own
    /// deterministic definition (same analysis, seed, jitter), not a region of the infinite
    /// solid. `n` must be a multiple of 32 ([`check_tileable_size`]). Held whole: see
    /// [`Self::synthesize_tileable_slabs`] for large ones.
    pub fn synthesize_tileable(
        &mut self,
        n: u32,
        progress: Progress,
        want_triples: bool,
    ) -> Result<(Volume, Vec<u32>)> {
        let mut whole = SlabsJoined::new([n; 3], self.color_channels(), want_triples);
        self.synthesize_tileable_slabs(n, progress, want_triples, |slab| whole.push(slab))?;
        Ok(whole.finish())
    }

    /// [`Self::synthesize_tileable`], handed to `sink` in slabs along z like
    /// [`Self::synthesize_slabs`]. When the periodic state fits one buffer of the backend (and
    /// the group size, [`SynthOptions::max_group`]) it is synthesized in one piece, its reads
    /// wrapping around the period; otherwise as boxes of the periodic solid, group by group,
    /// each with its dependency padding (see `Periodic::Unwrapped`): the same voxels either
    /// way (tested), so 256^3 and larger tileable solids work within lavapipe's 128 MiB
    /// buffers. The coarse-level cache does not apply (it belongs to the infinite solid).
    pub fn synthesize_tileable_slabs(
        &mut self,
        n: u32,
        progress: Progress,
        want_triples: bool,
        sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        let request = Request {
            region: Region::Tileable(n),
            want_triples,
            progress,
        };
        self.run(request, slabs_only(sink))
    }

    /// [`Region::Tileable`]'s work.
    pub(super) fn tileable_slabs(
        &mut self,
        n: u32,
        progress: Progress,
        want_triples: bool,
        mut sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        check_tileable_size(n)?;
        let periods = periods_below(n, ANALYSED_LEVELS);
        // One piece stores each level's period in whole bricks, which wrap (every period is
        // whole bricks: `check_tileable_size`); too large a period goes in groups.
        let max_group = self.group_limit(RequestKind::Volume);
        let one_piece = self.periodic_state_bytes(n, ANALYSED_LEVELS - 1) <= self.state_limit()
            && max_group.is_none_or(|side| side >= n);
        if !one_piece {
            if self.usage.is_some() {
                // Groups store padding voxels too, which would be counted.
                return Err(Error::Internal(
                    "usage counting needs a tileable solid synthesized in one piece".into(),
                ));
            }
            let whole = Box3::new([0; 3], [n as i32; 3]);
            let job = Job {
                exact: None,
                periodic: Periodic::Unwrapped(&periods),
                want_triples,
                max_group,
                progress,
            };
            return self.synthesize_slabs_of(whole, job, sink);
        }
        let levels = bricks::plan_periodic(n, &self.params.passes.levels());
        let output = levels.last().unwrap().bricks.clone();
        let mut stats = SynthStats {
            voxels_per_level: vec![0; ANALYSED_LEVELS],
            peak_state_bytes: 0,
            groups: 1,
        };
        self.deferring = false;
        let GroupResult {
            colors, triples, ..
        } = self.synthesize_group(
            levels,
            0,
            FirstLevel::Init,
            &output,
            Job {
                exact: None,
                periodic: Periodic::Wrapped(&periods),
                want_triples,
                max_group,
                progress,
            },
            &mut stats,
        )?;
        let colors = self.exec.finish_colors(colors)?;
        self.last_stats = Some(stats);
        let grid = BrickGrid::new(&output);
        let channels = self.color_channels() as usize;
        let mut volume = Volume::new(n, n, n, channels as u32);
        let mut out_triples = Vec::with_capacity(if want_triples {
            n as usize * n as usize * n as usize * 3
        } else {
            0
        });
        for z in 0..n as i32 {
            for y in 0..n as i32 {
                for x in 0..n as i32 {
                    let i = grid.voxel_index([x, y, z]).expect("every brick is output");
                    volume
                        .at_mut(x as u32, y as u32, z as u32)
                        .copy_from_slice(&colors[i].to_le_bytes()[..channels]);
                    if want_triples {
                        out_triples.extend_from_slice(&triples[i * 3..i * 3 + 3]);
                    }
                }
            }
        }
        progress("done", 1.0);
        sink(Slab {
            z0: 0,
            volume: &volume,
            triples: &out_triples,
        })
    }

    /// Bytes of a state holding one period `n`^3 of pack `pack`'s level.
    pub(super) fn periodic_state_bytes(&self, n: u32, pack: usize) -> u64 {
        (n as u64).pow(3) * (3 + self.packs[pack].pixel_words as u64) * 4
    }
}

#[cfg(test)]
mod tileable_tests {
    use super::super::request::{Job, Periodic};
    use super::*;
    use crate::analysis::{AnalysisInput, AnalysisParams};
    use crate::exemplar::Border;
    use crate::lazy::analyze;

    /// A tileable solid is exactly periodic: a box of the periodic solid shifted by part of a
    /// period holds the tileable volume's voxels rolled by that shift, for a period in one
    /// piece (64) and the smallest (32).
    #[test]
    fn tileable_solids_repeat_exactly_with_their_period() {
        let input = AnalysisInput {
            exemplars: vec![crate::exemplar::procedural::cobblestone(32, 5, 2)],
            masks: vec![],
            border: Border::Wrap,
            names: vec!["cobblestone".into()],
        };
        let params = AnalysisParams {
            balance_rounds: 0,
            ..Default::default()
        };
        let analysis = analyze(&input, &params, &Compute::Cpu, &|_, _| {}).unwrap();
        for n in [32i32, 64] {
            let mut s = Synthesizer::new(&analysis, SynthParams::default(), &Compute::Cpu).unwrap();
            let (whole, _) = s.synthesize_tileable(n as u32, &|_, _| {}, false).unwrap();
            let periods = periods_below(n as u32, ANALYSED_LEVELS);
            let shift = [n / 2 + 3, -n + 5, 2 * n - 7];
            let out = Box3::new(shift, shift.map(|v| v + 20));
            let mut shifted = Vec::new();
            let job = Job {
                exact: None,
                periodic: Periodic::Unwrapped(&periods),
                want_triples: false,
                max_group: None,
                progress: &|_, _| {},
            };
            s.synthesize_slabs_of(out, job, |slab| {
                shifted.extend_from_slice(&slab.volume.data);
                Ok(())
            })
            .unwrap();
            let c = whole.channels as usize;
            let mut i = 0;
            for z in 0..20 {
                for y in 0..20 {
                    for x in 0..20 {
                        let p = [x + shift[0], y + shift[1], z + shift[2]].map(|v| v.rem_euclid(n));
                        let want = whole.at(p[0] as u32, p[1] as u32, p[2] as u32);
                        assert_eq!(&shifted[i..i + c], want, "period {n}, voxel {x},{y},{z}");
                        i += c;
                    }
                }
            }
        }
    }
}
