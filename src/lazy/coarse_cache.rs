//! The coarse-level cache (`--coarse-cache N`): the infinite solid's levels above the finest
//! replaced by a tileable solid of period N/2 at level L-1, built once per synthesizer, so a
//! request synthesizes only its finest level (warm cuts in milliseconds).

use super::group::FirstLevel;
use super::group_plans::parent_level;
use super::request::{Job, Periodic};
use super::*;

impl Synthesizer {
    /// Level L-1 of the coarse cache: a tileable solid of period `coarse_cache / 2` there,
    /// synthesized through levels l_start..L-1 (once: the caller keeps it), its triples x
    /// fastest.
    fn build_coarse_cache(&mut self) -> Result<Vec<u32>> {
        let n = self.params.coarse_cache.expect("cache requested") / 2;
        let levels_above = ANALYSED_LEVELS - 1;
        // Built in one piece (its reads wrap around the period): one buffer must hold it.
        let state = self.periodic_state_bytes(n, levels_above - 1);
        if state > self.state_limit() {
            return Err(Error::invalid(
                format!("--coarse-cache {}", n * 2),
                format!(
                    "its periodic state ({} MiB) exceeds this backend's {} MiB per buffer: \
                     use a smaller period",
                    state >> 20,
                    self.state_limit() >> 20
                ),
            ));
        }
        let levels = bricks::plan_periodic(n, &self.params.passes.levels()[..levels_above]);
        let periods = periods_below(n, levels_above);
        let top = levels.last().unwrap().clone();
        let mut stats = SynthStats {
            voxels_per_level: vec![0; ANALYSED_LEVELS],
            ..Default::default()
        };
        let job = Job {
            exact: None,
            periodic: Periodic::Wrapped(&periods),
            want_triples: false,
            max_group: None,
            progress: &|_, _| {},
        };
        let r = self.synthesize_group(levels, 0, FirstLevel::Init, &[], job, &mut stats)?;
        let stride = 3 + self.packs[levels_above - 1].pixel_words as usize;
        let mut triples = Vec::with_capacity((n as usize).pow(3) * 3);
        for z in 0..n as i32 {
            for y in 0..n as i32 {
                for x in 0..n as i32 {
                    let i = top.grid.voxel_index([x, y, z]).expect("whole period") * stride;
                    triples.extend_from_slice(&r.state[i..i + 3]);
                }
            }
        }
        drop(r);
        // Requests read the coarse levels from the cache from now on.
        self.exec.release_coarse_levels(levels_above);
        Ok(triples)
    }

    /// One group through the coarse cache: level L-1 read from the cache (warped, periodic),
    /// then only the finest level synthesized.
    pub(super) fn synthesize_group_cached(
        &mut self,
        group: &[Brick],
        job: Job,
        stats: &mut SynthStats,
    ) -> Result<(exec::Colors, Vec<u32>)> {
        let finest = self
            .plan_of(group, job.exact, ANALYSED_LEVELS - 1)
            .pop()
            .unwrap();
        let parent = parent_level(&finest);
        if self.cache_buf.is_none() {
            let triples = self.build_coarse_cache()?;
            self.cache_buf = Some(self.exec.upload_index(triples));
        }
        self.synthesize_group(
            vec![parent, finest],
            ANALYSED_LEVELS - 2,
            FirstLevel::Cached,
            group,
            job,
            stats,
        )
        .map(|r| (r.colors, r.triples))
    }
}
