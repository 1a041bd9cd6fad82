//! One planned group of bricks synthesized: its first level's state (initialized, read from the
//! coarse-level cache, or given), then per level the upsampling, the correction passes and, at the
//! finest, the colours (and triples) of its output bricks.

use super::kernel_params;
use super::request::Job;
use super::*;

/// Where a planned synthesis's first level comes from.
pub(super) enum FirstLevel {
    /// `init`: the warped tiling of the candidate slab (l_start, or the periodic cache's build).
    Init,
    /// A state built elsewhere (the shared coarse levels), given whole.
    Given(exec::State),
    /// `init` reading the coarse-level cache (level L-1), warped by the jitter field.
    Cached,
}

/// What [`Synthesizer::synthesize_group`] returns.
pub(super) struct GroupResult {
    pub(super) colors: exec::Colors,
    pub(super) triples: Vec<u32>,
    /// The final state's words, when no colours were asked for.
    pub(super) state: Vec<u32>,
}

impl Synthesizer {
    /// Run a planned synthesis: colours (64 per brick, `group` order) and, when asked, triples
    /// of the output bricks `group`. `job.periodic`: whether and how the solid is tileable.
    /// `levels` are the packs `first_pack..`; `start`: where the first level's state comes from.
    /// An empty `group` skips the colours (the final state is returned).
    pub(super) fn synthesize_group(
        &mut self,
        levels: Vec<SparseLevel>,
        first_pack: usize,
        start: FirstLevel,
        group: &[Brick],
        job: Job,
        stats: &mut SynthStats,
    ) -> Result<GroupResult> {
        let Job {
            periodic,
            progress,
            want_triples,
            ..
        } = job;
        let recording = std::time::Instant::now();
        // Each level's brick index is built when the level starts and dropped after it (with
        // the level's sub-pass plans): a large box's indices are several bytes per voxel.
        let mut levels = levels;
        let last = levels.len() - 1;
        let index_of = |exec: &mut exec::Executor, levels: &[SparseLevel], l: usize| {
            let timer = std::time::Instant::now();
            let mut layout = IndexLayout::new(
                &levels[l],
                l.checked_sub(1).map(|p| &levels[p]),
                (l == last).then_some(group),
            );
            let built = ms(timer);
            let index = exec.upload_index(std::mem::take(&mut layout.words));
            tracing::debug!(
                "level {l}: brick index in {:.1} ms (built in {built:.1} ms)",
                ms(timer)
            );
            (layout, index)
        };
        let mut state_bytes = 0u64;
        for (l, lv) in levels.iter().enumerate() {
            // A first level given whole or read from the cache was synthesized elsewhere.
            if l > 0 || matches!(start, FirstLevel::Init) {
                stats.voxels_per_level[first_pack + l] += lv.voxels();
            }
            let pixel_words = self.packs[first_pack + l].pixel_words;
            let words = lv.voxels() * (3 + pixel_words as u64);
            // With its pass-start copy where the backend keeps one.
            state_bytes = state_bytes.max(words * 4 * self.exec.state_copies(pixel_words));
        }
        stats.peak_state_bytes = stats.peak_state_bytes.max(state_bytes);
        let (mut layout, mut index) = index_of(&mut self.exec, &levels, 0);
        let seed_lo = self.params.seed as u32;
        let seed_hi = (self.params.seed >> 32) as u32;
        let init = kernel_params::init_params(
            &self.packs[first_pack],
            self.border,
            (layout.storage_list, levels[0].bricks.len() as u32),
            periodic.init_period(),
            self.params.seed,
            self.params.jitter,
        );
        progress("level 0: init", 0.0);
        let mut state = match start {
            FirstLevel::Given(s) => s,
            FirstLevel::Init => exec::timed(&mut self.exec, &mut self.times, "init", |e| {
                e.init(first_pack, &init, &index, None)
            })?,
            FirstLevel::Cached => {
                let n = self.params.coarse_cache.expect("cache requested") / 2;
                // A hashed offset so different seeds read the cache at different places.
                let [tile_x, tile_y, tile_z] =
                    [0x71u32, 0x72, 0x73].map(|k| hash32(seed_lo ^ seed_hi ^ k) % n);
                let cached = crate::contract::uniforms::InitParams {
                    period: 0,
                    cache_period: n,
                    tile_x,
                    tile_y,
                    tile_z,
                    ..init
                };
                let cache = self.cache_buf.as_ref().expect("cache uploaded");
                exec::timed(&mut self.exec, &mut self.times, "init", |e| {
                    e.init(first_pack, &cached, &index, Some(cache))
                })?
            }
        };
        for level in 0..levels.len() {
            if level > 0 {
                // The previous level's dispatches go to the GPU while this level's index is
                // built (and its buffers are freed once they have run).
                self.exec.flush()?;
                (layout, index) = index_of(&mut self.exec, &levels, level);
                // The parent's sub-pass plans are done with.
                levels[level - 1].subpasses = Vec::new();
            }
            let lv = &levels[level];
            let pack_index = first_pack + level;
            let pack = &self.packs[pack_index];
            if level > 0 {
                let up = kernel_params::upsample_params(
                    pack,
                    self.border,
                    &levels[level - 1].grid,
                    layout.parent_table,
                    (layout.storage_list, lv.bricks.len() as u32),
                );
                state = exec::timed(&mut self.exec, &mut self.times, "upsample", |e| {
                    e.upsample(pack_index, &up, state, &index)
                })?;
                // Submitted alone, so the parent's state is freed as soon as it has run (a warm
                // session keeps it for its next request instead: `keep_buffers`).
                self.exec.flush()?;
            }
            progress(
                &format!("level {level}: correction"),
                (level as f32 + 0.1) / levels.len() as f32,
            );
            let k3d_used = pack.k3d_used(pack_index + 1 == self.packs.len());
            // One correction pass at a time: its sub-passes' parameters, then the pass.
            let mut pass: Vec<CorrectParams> = Vec::with_capacity(SUBPASS_ORDER.len());
            for (s, sp) in lv.subpasses.iter().enumerate() {
                if !sp.is_empty() {
                    let mut p = kernel_params::correct_params(
                        pack,
                        &lv.grid,
                        (layout.subpass_lists[s].0, layout.subpass_lists[s].1),
                        sp.class,
                        k3d_used,
                        self.border,
                        self.params.candidates,
                    );
                    p.mask_offset = layout.subpass_lists[s].2;
                    p.period = periodic.read_period(level);
                    pass.push(p);
                }
                if (s + 1) % SUBPASS_ORDER.len() == 0 || s + 1 == lv.subpasses.len() {
                    if !pass.is_empty() {
                        self.check_cancelled()?;
                        exec::timed(&mut self.exec, &mut self.times, "correct", |e| {
                            e.correct_pass(pack_index, &pass, &mut state, &index)
                        })?;
                    }
                    pass.clear();
                }
            }
            if let Some(usage) = self.usage.as_mut() {
                let words = self.exec.read_state(&state)?;
                let stride = 3 + pack.pixel_words as usize;
                let counts = &mut usage[pack_index];
                for voxel in words.chunks_exact(stride) {
                    for (a, count) in counts.iter_mut().enumerate() {
                        let (x, y) = crate::contract::triple::unpack(voxel[a]);
                        count[(y * pack.width + x) as usize] += 1;
                    }
                }
            }
        }
        if group.is_empty() {
            return Ok(GroupResult {
                colors: exec::Colors::Ready(Vec::new()),
                triples: Vec::new(),
                state: self.exec.read_state(&state)?,
            });
        }
        let finest = levels.last().unwrap();
        let pack = self.packs.last().unwrap();
        let c = kernel_params::colorize_params(
            pack,
            self.border,
            &finest.grid,
            (layout.output_list, group.len() as u32),
            self.params.color.kernel_code(),
            periodic.read_period(last),
        );
        tracing::debug!("group's kernels recorded in {:.1} ms", ms(recording));
        // In a request of several groups the colours may come back while the next group runs
        // (see `for_each_group`); with triples they are needed now.
        let defer = self.deferring && !want_triples;
        let colors = exec::timed(&mut self.exec, &mut self.times, "colorize", |e| {
            let colors = e.colorize(first_pack + last, &c, &state, &index)?;
            match defer {
                true => Ok(colors),
                false => e.finish_colors(colors).map(exec::Colors::Ready),
            }
        })?;
        let mut triples = Vec::new();
        if want_triples {
            let words = self.exec.read_state(&state)?;
            let stride = 3 + pack.pixel_words as usize;
            triples.reserve(group.len() * 64 * 3);
            for b in group {
                for l in 0..64 {
                    let i = finest
                        .grid
                        .voxel_index(bricks::voxel_of(*b, l))
                        .expect("output bricks are stored")
                        * stride;
                    triples.extend_from_slice(&words[i..i + 3]);
                }
            }
        }
        Ok(GroupResult {
            colors,
            triples,
            state: Vec::new(),
        })
    }
}
