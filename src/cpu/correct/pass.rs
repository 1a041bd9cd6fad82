//! Running a correction pass: runs of bricks along x in parallel, one window each; a pass of
//! whole bricks brick by brick, without a copy of the state.

use super::*;

/// The list's entries with a class voxel to correct, as runs (first entry, count) of up to
/// [`MAX_RUN`] bricks consecutive along x, in list order.
pub(super) fn runs_of(ctx: &Ctx) -> Vec<(u32, u32)> {
    let p = ctx.p;
    let mut runs: Vec<(u32, u32)> = Vec::new();
    let mut i = 0;
    while i < p.list_count {
        if ctx.mask(i) == 0 {
            i += 1;
            continue;
        }
        let first = brick_at(ctx.bricks, p.list_offset, i);
        let mut n = 1;
        while n < MAX_RUN as u32
            && i + n < p.list_count
            && ctx.mask(i + n) != 0
            && brick_at(ctx.bricks, p.list_offset, i + n)
                == [first[0] + n as i32, first[1], first[2]]
        {
            n += 1;
        }
        runs.push((i, n));
        i += n;
    }
    runs
}

/// `f` over `runs` in parallel, each thread with a window of its own; the outputs of each
/// thread's share, in order.
pub(super) fn in_parallel<T: Send>(
    runs: &[(u32, u32)],
    f: impl Fn(&mut Window, u32, u32, &mut Vec<T>) + Sync,
) -> Vec<Vec<T>> {
    runs.par_iter()
        .fold(
            || (Box::new(Window::new()), Vec::new()),
            |(mut window, mut out), &(i, n)| {
                f(&mut window, i, n, &mut out);
                (window, out)
            },
        )
        .map(|(_, out)| out)
        .collect()
}

/// [`runs_of`] `ctx`'s list, `f` over them in parallel ([`in_parallel`]).
pub(super) fn over_runs<T: Send>(
    ctx: &Ctx,
    f: impl Fn(&mut Window, u32, u32, &mut Vec<T>) + Sync,
) -> Vec<Vec<T>> {
    in_parallel(&runs_of(ctx), f)
}

/// One correction pass: its sub-passes `ps` in order, each [`correct_prepared`] of the state
/// as the earlier ones left it, with `pass_start` (overwritten) the state as the pass began.
/// When every sub-pass lists the same whole bricks (the planner's passes do) and voxels hold
/// one value word, brick by brick instead: a brick's eight sub-passes read one window copied
/// from the pass-start state, with the brick's own voxels updated in it as they go (the same
/// results: a brick's sub-passes see only its own voxels' updates), so a pass copies each
/// window once instead of once per sub-pass. That path needs no pass-start copy either
/// (`whole_brick_pass_in_place`); `pass_start` is then left empty. `by_bricks`: whether that
/// path may be taken (tests compare it with the sub-pass-by-sub-pass reference).
pub fn correct_pass(
    prepared: &Prepared,
    ps: &[CorrectParams],
    level: &[u32],
    state: &mut [u32],
    pass_start: &mut Vec<u32>,
    bricks: &[u32],
    by_bricks: bool,
) {
    if by_bricks && whole_brick_pass(ps, bricks) {
        assert!(prepared.fits(&ps[0]), "prepared for another level layout");
        pass_start.clear();
        pass_start.shrink_to_fit();
        whole_brick_pass_in_place(prepared, ps, level, state, bricks);
        return;
    }
    pass_start.clear();
    pass_start.extend_from_slice(state);
    for p in ps {
        let updates = correct_prepared(prepared, p, level, state, pass_start, bricks);
        apply(p, level, state, &updates);
    }
}

/// A whole-brick pass without a copy of the state: bricks are corrected a block of z layers of
/// bricks at a time (the block's runs in parallel), and a block's results are held back until
/// the next block is done. A voxel's reads reach 2 voxels, so the bricks of a layer read the
/// layers beside it only: when a block is corrected, it and the block before it still hold
/// their pass-start values in `state` (their results are held), and the block before can then
/// be written, no block left to read it. A periodic state's first block is read by its last
/// (the wrap), so its results wait for the end. Memory: two blocks' results instead of two
/// whole states. A block is one layer, or as many as it takes to give every thread a few runs
/// (a thin shell's groups have few bricks per layer, and each block ends with a wait), up to an
/// eighth of the pass's runs: the held results stay under about a quarter of the state.
pub(super) fn whole_brick_pass_in_place(
    prepared: &Prepared,
    ps: &[CorrectParams],
    level: &[u32],
    state: &mut [u32],
    bricks: &[u32],
) {
    // The runs, by z layer of bricks (ascending; list order within a layer).
    let mut layers: std::collections::BTreeMap<i32, Vec<(u32, u32)>> = Default::default();
    {
        let ctxs = sub_pass_contexts(prepared, ps, level, state, bricks);
        for (i, n) in runs_of(&ctxs[0]) {
            let z = brick_at(bricks, ps[0].list_offset, i)[2];
            layers.entry(z).or_default().push((i, n));
        }
    }
    // A few runs per thread, but no more than an eighth of the pass (so that the held results
    // stay within about a quarter of the state on a many-core machine, which would otherwise
    // merge a small group's layers into one block).
    let total: usize = layers.values().map(Vec::len).sum();
    let min_runs = (8 * rayon::current_num_threads()).min(total / 8);
    let mut blocks: Vec<Vec<(u32, u32)>> = Vec::new();
    for runs in layers.into_values() {
        match blocks.last_mut() {
            Some(block) if block.len() < min_runs => block.extend(runs),
            _ => blocks.push(runs),
        }
    }
    let periodic = ps[0].period != 0;
    type Results = Vec<Vec<(usize, [u32; 256])>>;
    let mut previous: Option<Results> = None;
    let mut first: Option<Results> = None;
    for (k, runs) in blocks.iter().enumerate() {
        let results = {
            let ctxs = sub_pass_contexts(prepared, ps, level, state, bricks);
            in_parallel(runs, |window, i, n, out| {
                fused_run_dispatch(&ctxs, window, i, n, out)
            })
        };
        // The block below has no reader left.
        if let Some(below) = previous.take() {
            write_bricks(state, &below);
        }
        if periodic && k == 0 {
            first = Some(results);
        } else {
            previous = Some(results);
        }
    }
    for results in [previous, first].into_iter().flatten() {
        write_bricks(state, &results);
    }
}

/// The sub-passes' contexts, reading the state `state` (also as the pass-start state).
pub(super) fn sub_pass_contexts<'a>(
    prepared: &'a Prepared,
    ps: &'a [CorrectParams],
    level: &'a [u32],
    state: &'a [u32],
    bricks: &'a [u32],
) -> Vec<Ctx<'a>> {
    ps.iter()
        .map(|p| Ctx {
            p,
            level,
            level_bytes: bytemuck::cast_slice(level),
            prepared,
            state,
            pass_start: state,
            bricks,
            grid_lo: [p.grid_lo_x, p.grid_lo_y, p.grid_lo_z],
            grid_dims: [p.grid_x, p.grid_y, p.grid_z],
        })
        .collect()
}

/// Write corrected bricks (their first state index and 64 voxels' words) into the state.
pub(super) fn write_bricks(state: &mut [u32], results: &[Vec<(usize, [u32; 256])>]) {
    for (base, words) in results.iter().flatten() {
        state[base * 4..(base + 64) * 4].copy_from_slice(words);
    }
}

/// Whether the sub-passes of a pass all list the same bricks, each whole (mask 0xFF) or not at
/// all, each class once, with one value word per voxel and whole-brick periods: what the
/// brick-by-brick pass needs.
pub(super) fn whole_brick_pass(ps: &[CorrectParams], bricks: &[u32]) -> bool {
    let Some(p0) = ps.first() else { return false };
    let mut classes = 0u32;
    for p in ps {
        classes |= 1 << (p.class_x | p.class_y << 1 | p.class_z << 2);
    }
    let mask = |p: &CorrectParams, i: u32| {
        (bricks[(p.mask_offset + i / 4) as usize] >> ((i % 4) * 8)) & 0xFF
    };
    classes.count_ones() as usize == ps.len()
        && ps.iter().all(|p| {
            p.ex.pixel_words == 1
                && p.period % 4 == 0
                && p.list_count == p0.list_count
                && (0..p.list_count).all(|i| {
                    let m = mask(p, i);
                    (m == 0 || m == 0xFF)
                        && m == mask(p0, i)
                        && brick_at(bricks, p.list_offset, i) == brick_at(bricks, p0.list_offset, i)
                })
        })
}

/// [`fused_run`], with AVX2 when the CPU has it (as [`Ctx::correct_run_dispatch`]).
pub(super) fn fused_run_dispatch(
    ctxs: &[Ctx],
    window: &mut Window,
    i: u32,
    n: u32,
    out: &mut Vec<(usize, [u32; 256])>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { fused_run_avx2(ctxs, window, i, n, out) };
    }
    fused_run::<false>(ctxs, window, i, n, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) fn fused_run_avx2(
    ctxs: &[Ctx],
    window: &mut Window,
    i: u32,
    n: u32,
    out: &mut Vec<(usize, [u32; 256])>,
) {
    fused_run::<true>(ctxs, window, i, n, out)
}

/// A pass over the run of `n` bricks from list entry `i`: per brick, its sub-passes in order
/// on the window, then its 64 voxels (state records) appended to `out` with their first index.
#[inline(always)]
pub(super) fn fused_run<const MADD: bool>(
    ctxs: &[Ctx],
    window: &mut Window,
    i: u32,
    n: u32,
    out: &mut Vec<(usize, [u32; 256])>,
) {
    let first_ctx = &ctxs[0];
    let p0 = first_ctx.p;
    let first = brick_at(first_ctx.bricks, p0.list_offset, i);
    window.fill_all(first_ctx, first, n as i32);
    let pixels = [p0.ex.pixels0, p0.ex.pixels1, p0.ex.pixels2];
    let mut saved = BrickCopy::new();
    for m in 0..n as i32 {
        let b = [first[0] + m, first[1], first[2]];
        let base = first_ctx
            .state_index(b.map(|v| v * 4))
            .expect("active bricks are stored");
        // The brick's pass-start voxels, for the next bricks' reads.
        for l in 0..64 {
            let s = Window::brick_slot(m, l);
            saved.values[l] = window.values[s];
            saved.triples[l] = window.triples[s];
        }
        for ctx in ctxs {
            let p = ctx.p;
            let class = [p.class_x as i32, p.class_y as i32, p.class_z as i32];
            // A sub-pass's voxels read each other's values from before it: all eight first.
            let mut found = [(0usize, [0u32; 3]); 8];
            for (k, f) in found.iter_mut().enumerate() {
                let local = [
                    class[0] + 2 * (k as i32 & 1),
                    class[1] + 2 * ((k as i32 >> 1) & 1),
                    class[2] + 2 * (k as i32 >> 2),
                ];
                let pos = [0, 1, 2].map(|a| b[a] * 4 + local[a]);
                let l = (local[2] * 16 + local[1] * 4 + local[0]) as usize;
                *f = (l, ctx.correct_voxel::<MADD>(&*window, pos));
            }
            for (l, t) in found {
                let s = Window::brick_slot(m, l);
                let mut record = [0u32; 4];
                write_voxel(
                    &mut record,
                    ctx.level,
                    t,
                    pixels,
                    p.ex.width,
                    1,
                    p.ex.channels,
                );
                window.triples[s] = t;
                window.values[s] = record[3];
            }
        }
        let mut words = [0u32; 256];
        for (l, w) in words.chunks_exact_mut(4).enumerate() {
            let s = Window::brick_slot(m, l);
            let t = window.triples[s];
            w.copy_from_slice(&[t[0], t[1], t[2], window.values[s]]);
            window.values[s] = saved.values[l];
            window.triples[s] = saved.triples[l];
        }
        out.push((base, words));
    }
}
