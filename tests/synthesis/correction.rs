//! Kernel semantics on constructed states: the correction keeps an exact exemplar plane, whole-brick passes equal the sub-pass reference, the coarse cache keeps spatial determinism.

use super::*;

/// A state in which every voxel's three coordinates are its position along (a+1, a+2) (mod the
/// exemplar size): each voxel is an exemplar pixel, so the plane of E_a through any voxel IS an
/// exemplar neighbourhood. The 2D search of exemplar a must find that very pixel (distance 0) and
/// keep it, for every voxel: this pins the gather order, plane orientation and projection.
#[test]
fn correction_keeps_an_exact_exemplar_plane() {
    for axis in 0..3 {
        exact_plane_is_kept(axis);
    }
}

fn exact_plane_is_kept(axis: usize) {
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let pack = LevelPack::new(&a, 0);
    let (w, h) = (pack.width, pack.height);
    let n = 20i32;
    let lo = [-3, 5, -7];
    let stored = bricks::bricks_of_box(Box3::new(lo, [lo[0] + n, lo[1] + n, lo[2] + n]));
    let grid = bricks::BrickGrid::new(&stored);
    let stride = 3 + pack.pixel_words as usize;
    let o = &pack.offsets;
    let mut state = vec![0u32; stored.len() * 64 * stride];
    for b in &stored {
        for l in 0..64 {
            {
                let pos = bricks::voxel_of(*b, l);
                let i = grid.voxel_index(pos).unwrap() * stride;
                let c = pack_coord(pos[(axis + 1) % 3], pos[(axis + 2) % 3], w, h);
                solidsynth::cpu::synth_common::write_voxel(
                    &mut state[i..i + stride],
                    &pack.words,
                    [c, c, c],
                    o.pixels,
                    w,
                    pack.pixel_words,
                    pack.channels,
                );
            }
        }
    }
    // Bricks whose voxels' reads (two voxels away) stay inside the stored ones: the interior.
    let interior: Vec<_> = stored
        .iter()
        .copied()
        .filter(|b| {
            (0..27).all(|k| {
                grid.slot([b[0] + k % 3 - 1, b[1] + (k / 3) % 3 - 1, b[2] + k / 9 - 1])
                    .is_some()
            })
        })
        .collect();
    assert!(interior.len() >= 8);
    let mut index = grid.table.clone();
    let list = bricks::push_list(&mut index, &interior);
    // Every class voxel of every listed brick is needed.
    let masks = index.len() as u32;
    index.extend(std::iter::repeat_n(u32::MAX, interior.len().div_ceil(4)));
    // The CPU reference scores candidates from per-level tables, or (exemplars too large for
    // them) from the level data directly: the same updates, on scrambled triples, in both modes.
    let mut scrambled = state.clone();
    for (v, voxel) in scrambled.chunks_exact_mut(stride).enumerate() {
        let t = [0, 1, 2].map(|a| {
            let r = (v as u32)
                .wrapping_mul(2_654_435_761)
                .rotate_left(7 * a as u32 + 3);
            solidsynth::analysis::frame::pack(r % w, (r >> 16) % h)
        });
        solidsynth::cpu::synth_common::write_voxel(
            voxel,
            &pack.words,
            t,
            o.pixels,
            w,
            pack.pixel_words,
            pack.channels,
        );
    }
    for mode in [CandidateMode::TwoD, CandidateMode::ThreeD] {
        let p = solidsynth::contract::uniforms::CorrectParams {
            mask_offset: masks,
            ..solidsynth::lazy::kernel_params::correct_params(
                &pack,
                &grid,
                (list, interior.len() as u32),
                3,
                4,
                0,
                mode,
            )
        };
        use solidsynth::cpu::correct::{correct, correct_prepared, Prepared};
        let direct = Prepared::new(&p, &pack.words).without_tables();
        let with_tables: Vec<_> = correct(&p, &pack.words, &scrambled, &scrambled, &index)
            .iter()
            .collect();
        let without: Vec<_> =
            correct_prepared(&direct, &p, &pack.words, &scrambled, &scrambled, &index)
                .iter()
                .collect();
        assert_eq!(with_tables, without, "{mode:?}: tables change the result");
        let moved = with_tables
            .iter()
            .filter(|(i, t)| t[..] != scrambled[i * stride..i * stride + 3])
            .count();
        assert!(moved > 0, "{mode:?}: the search changed nothing");
    }
    // 2D mode: exemplar `axis`'s own search decides its coordinate.
    for class in [0, 5] {
        let p = solidsynth::lazy::kernel_params::correct_params(
            &pack,
            &grid,
            (list, interior.len() as u32),
            class,
            4,
            0,
            CandidateMode::TwoD,
        );
        let p = solidsynth::contract::uniforms::CorrectParams {
            mask_offset: masks,
            ..p
        };
        let updates = solidsynth::cpu::correct::correct(&p, &pack.words, &state, &state, &index);
        assert_eq!(updates.len(), interior.len() * 8);
        let mut kept = 0;
        for (i, t) in updates.iter() {
            if t[axis] == state[i * stride + axis] {
                kept += 1;
            }
        }
        assert_eq!(
            kept,
            updates.len(),
            "exemplar {axis}: the exact plane match was not kept everywhere"
        );
    }
}

fn pack_coord(u: i32, v: i32, w: u32, h: u32) -> u32 {
    pack(u.rem_euclid(w as i32) as u32, v.rem_euclid(h as i32) as u32)
}

#[allow(dead_code)]
fn coords(c: u32) -> (u32, u32) {
    unpack(c)
}

/// With the coarse-level cache the solid is another deterministic function of space: any box
/// equals the same voxels of a larger one, and sparse samples equal the box's.
#[test]
fn coarse_cache_solids_are_spatially_deterministic() {
    use solidsynth::backend::Compute;
    use solidsynth::lazy::{Box3, SynthOptions, SynthParams, Synthesizer};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = SynthParams {
        seed: 6,
        coarse_cache: Some(64),
        ..Default::default()
    };
    let big = Box3::new([-20, -7, 3], [13, 9, 21]);
    let mut s = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    let v = s.synthesize(big, &|_, _| {}).unwrap();
    let small = Box3::new([-3, -2, 10], [5, 4, 17]);
    let mut fresh = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    let sv = fresh.synthesize(small, &|_, _| {}).unwrap();
    for z in small.lo[2]..small.hi[2] {
        for y in small.lo[1]..small.hi[1] {
            for x in small.lo[0]..small.hi[0] {
                let at = |b: Box3| {
                    [
                        (x - b.lo[0]) as u32,
                        (y - b.lo[1]) as u32,
                        (z - b.lo[2]) as u32,
                    ]
                };
                let (p, q) = (at(small), at(big));
                assert_eq!(
                    sv.at(p[0], p[1], p[2]),
                    v.at(q[0], q[1], q[2]),
                    "voxel {x},{y},{z}"
                );
            }
        }
    }
    // In groups of 8^3 whose plans are made several at a time (`plan_ahead`, one per thread
    // of a 3-thread pool): the same voxels.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let (grouped, groups) = pool.install(|| {
        let mut g = Synthesizer::with_options(
            &a,
            params.clone(),
            &Compute::Cpu,
            SynthOptions {
                max_group: Some(8),
                ..Default::default()
            },
        )
        .unwrap();
        let out = g.synthesize(big, &|_, _| {}).unwrap();
        (out, g.last_stats().unwrap().groups)
    });
    assert!(groups > 3, "{groups} groups");
    assert!(grouped == v, "the cached box in groups differs");
    // Only the finest level is synthesized per request.
    let stats = fresh.last_stats().unwrap();
    assert_eq!(stats.voxels_per_level[0], 0);
    // The cache changes the solid (it is another definition), and bad periods are refused.
    let plain = Synthesizer::new(
        &a,
        SynthParams {
            coarse_cache: None,
            ..params.clone()
        },
        &Compute::Cpu,
    )
    .unwrap()
    .synthesize(small, &|_, _| {})
    .unwrap();
    assert_ne!(plain, sv);
    assert!(SynthParams {
        coarse_cache: Some(96),
        ..params
    }
    .validate()
    .is_err());
}

/// The CPU backend's passes of whole bricks (corrected in blocks of z layers in place, each
/// block's results held back until the next is done) equal the sub-pass-by-sub-pass reference
/// against a copy of the state as the pass began: on a box across negative coordinates, in
/// groups, and on tileable solids (whose first layer is read by the last across the wrap), at
/// one thread (one layer a block) and at many (blocks of several layers).
#[test]
fn brick_by_brick_passes_equal_the_sub_pass_reference() {
    use solidsynth::backend::Compute;
    use solidsynth::lazy::{SynthOptions, SynthParams, Synthesizer};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = SynthParams {
        seed: 9,
        ..Default::default()
    };
    let run = |reference: bool, threads: usize, group: Option<u32>| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let options = SynthOptions {
                max_group: group,
                ..Default::default()
            };
            let mut s =
                Synthesizer::with_options(&a, params.clone(), &Compute::Cpu, options).unwrap();
            s.set_sub_pass_reference(reference);
            let b = s
                .synthesize(Box3::new([-21, -6, -13], [19, 18, 7]), &|_, _| {})
                .unwrap();
            // A tall thin box: layers of few runs, merged into blocks of several layers.
            let tall = s
                .synthesize(Box3::new([-5, -3, -40], [3, 5, 120]), &|_, _| {})
                .unwrap();
            let t = s.synthesize_tileable(32, &|_, _| {}, false).unwrap().0;
            (b, tall, t)
        })
    };
    let reference = run(true, 2, None);
    for (threads, group) in [(1, None), (2, None), (7, Some(16)), (16, None)] {
        let (b, tall, t) = run(false, threads, group);
        assert!(b == reference.0, "box, {threads} threads, groups {group:?}");
        assert!(
            tall == reference.1,
            "tall box, {threads} threads, groups {group:?}"
        );
        assert!(
            t == reference.2,
            "tileable, {threads} threads, groups {group:?}"
        );
    }
}
