//! Whole syntheses through the four synthesis kernels (`init`, `upsample`, `correct`,
//! `colorize`, each tested alone in its own file): GPU and CPU bit-exact, on states built from a
//! real analysis (random states would not exercise the candidate logic), in boxes with negative
//! coordinates, for both candidate modes, shared and three-exemplar analyses, wrap and mirror,
//! in groups, with shared coarse levels, the coarse cache and warm cut sessions.

use crate::compare::words_equal;
use crate::synth_inputs::{analysis, analyze, fixture};
use solidsynth::backend::{BackendChoice, Compute};
use solidsynth::exemplar::Border;
use solidsynth::gpu::GpuOptions;
use solidsynth::lazy::{Box3, CandidateMode, ColorSource, SynthOptions, SynthParams, Synthesizer};

/// Whole box syntheses run every kernel in sequence (init, upsample, 8 sub-passes x passes per
/// level, colorize) on both backends; any kernel differing makes the volumes differ.
#[test]
fn synthesis_kernels_bit_exact_on_gpu_and_cpu() {
    let _serial = crate::serial();
    let Some(gpu) = gpu_backend() else { return };
    let cases = [
        (
            false,
            Border::Wrap,
            CandidateMode::ThreeD,
            1.0,
            Box3::new([-5, 3, -9], [7, 13, 2]),
        ),
        (
            true,
            Border::Mirror,
            CandidateMode::ThreeD,
            2.5,
            Box3::new([0, 0, 0], [10, 8, 12]),
        ),
        (
            false,
            Border::Mirror,
            CandidateMode::TwoD,
            0.0,
            Box3::new([100, -50, 7], [109, -41, 16]),
        ),
    ];
    let colors = [ColorSource::Matched, ColorSource::X, ColorSource::Z];
    for ((three, border, mode, jitter, b), color) in cases.into_iter().zip(colors) {
        let a = analysis(three, border);
        let params = SynthParams {
            seed: 77,
            jitter,
            candidates: mode,
            passes: solidsynth::lazy::PassSchedule::uniform(2),
            color,
            coarse_cache: None,
        };
        let what = format!("three={three} {border:?} {mode:?} jitter={jitter} {color:?} {b:?}");
        same_on_both(&what, &a, &params, &gpu, Default::default(), |s| {
            s.synthesize(b, &|_, _| {}).unwrap()
        });
    }
    // The fitted colours, which read the final level's neighbours (2 voxels more of it planned
    // around the box, or wrapped around a tileable solid's period).
    let a = analysis(true, Border::Mirror);
    let params = SynthParams {
        seed: 79,
        color: ColorSource::Fitted,
        ..Default::default()
    };
    same_on_both(
        "fitted colours",
        &a,
        &params,
        &gpu,
        Default::default(),
        |s| {
            s.synthesize(Box3::new([-3, 5, -8], [9, 14, 1]), &|_, _| {})
                .unwrap()
        },
    );
    same_on_both(
        "fitted, tileable",
        &a,
        &params,
        &gpu,
        Default::default(),
        |s| s.synthesize_tileable(32, &|_, _| {}, false).unwrap().0,
    );
    // A one-voxel-thick slab (an axis-aligned cut's request): its bricks and their padding.
    // (Passes compute whole bricks, so every brick mask here is full.)
    let a = analysis(false, Border::Wrap);
    let params = SynthParams {
        seed: 78,
        ..Default::default()
    };
    let thin = Box3::new([-6, 1, 5], [13, 22, 6]);
    same_on_both(
        "one-voxel-thick slab",
        &a,
        &params,
        &gpu,
        Default::default(),
        |s| s.synthesize(thin, &|_, _| {}).unwrap(),
    );
    // Four channels (RGB + feature: one value word per voxel) and five (RGBA + feature: two
    // words; the CPU correction reads those through the brick index, not a window). Also with
    // the projection weights as bytes (`GpuOptions::byte_weights`, for packed dot products on
    // hardware GPUs): one pixel word, and two with three bytes past the channels.
    let bytes_gpu = Compute::open(
        BackendChoice::Gpu,
        &GpuOptions {
            byte_weights: true,
            ..GpuOptions::from_env()
        },
    )
    .unwrap();
    for rgba in [false, true] {
        let cells = fixture(include_bytes!("../tests/fixtures/cells32.png"));
        let exemplar = if rgba {
            let mut e = solidsynth::exemplar::Image::new(32, 32, 4);
            for (i, (d, s)) in e
                .pixels
                .chunks_exact_mut(4)
                .zip(cells.pixels.chunks_exact(3))
                .enumerate()
            {
                d[..3].copy_from_slice(s);
                d[3] = (i * 7 % 256) as u8;
            }
            e
        } else {
            cells
        };
        let mut mask = solidsynth::exemplar::Image::new(32, 32, 1);
        for (i, m) in mask.pixels.iter_mut().enumerate() {
            *m = if (i % 32) / 8 % 2 == 0 { 255 } else { 0 };
        }
        let a = analyze(vec![exemplar], vec![mask], Border::Wrap);
        assert_eq!(
            a.exemplar(0).levels[0].image.channels,
            if rgba { 5 } else { 4 }
        );
        // Matched colours: with four colour channels (rgba) every byte of the table is used.
        let params = SynthParams {
            seed: 3,
            color: ColorSource::Matched,
            ..Default::default()
        };
        let b = Box3::new([-3, 5, 0], [9, 13, 10]);
        same_on_both(
            &format!("feature, rgba={rgba}"),
            &a,
            &params,
            &gpu,
            Default::default(),
            |s| s.synthesize(b, &|_, _| {}).unwrap(),
        );
        let what = format!("feature, rgba={rgba}, byte weights");
        same_on_both(&what, &a, &params, &bytes_gpu, Default::default(), |s| {
            s.synthesize(b, &|_, _| {}).unwrap()
        });
        if rgba {
            // A source per channel for all four colour channels (two value words per voxel).
            let params = SynthParams {
                color: "x,matched,average,z".parse().unwrap(),
                ..params
            };
            same_on_both(
                "feature, rgba, per channel",
                &a,
                &params,
                &gpu,
                Default::default(),
                |s| s.synthesize(b, &|_, _| {}).unwrap(),
            );
        }
    }
    // Odd exemplar sizes (27, 14, 7, 4: children one pixel wider than twice their parent's
    // coordinates reach, so upsampling resolves past the edge) on both borders.
    for border in [Border::Wrap, Border::Mirror] {
        let cells = fixture(include_bytes!("../tests/fixtures/cells32.png"));
        let a = analyze(vec![cells.crop(2, 3, 27, 27)], vec![], border);
        assert_eq!(a.exemplar(0).levels[0].image.width, 27);
        let params = SynthParams {
            seed: 11,
            ..Default::default()
        };
        let b = Box3::new([-4, 6, -2], [8, 14, 9]);
        same_on_both(
            &format!("odd size, {border:?}"),
            &a,
            &params,
            &gpu,
            Default::default(),
            |s| s.synthesize(b, &|_, _| {}).unwrap(),
        );
    }
    // Weights beyond 16 bits (analyses before revision 2): the GPU reads them unpacked and the
    // CPU backend without its 16-bit multiply-adds.
    let mut a = analysis(false, Border::Wrap);
    for level in &mut a.exemplars[0].levels {
        level.pca.weights[5] = 40_000;
    }
    let params = SynthParams {
        seed: 12,
        ..Default::default()
    };
    let b = Box3::new([-2, -7, 3], [9, 2, 12]);
    same_on_both(
        "weights beyond 16 bits",
        &a,
        &params,
        &gpu,
        Default::default(),
        |s| s.synthesize(b, &|_, _| {}).unwrap(),
    );
    let a = analysis(false, Border::Wrap);
    // A parameter arena of 1 KiB (a few dispatches): each level's batch is submitted in parts,
    // whenever the arena is full.
    let params = SynthParams {
        seed: 13,
        ..Default::default()
    };
    same_on_both(
        "small parameter arena",
        &a,
        &params,
        &gpu,
        Default::default(),
        |s| {
            s.set_parameter_arena_bytes(1024).unwrap();
            s.synthesize(b, &|_, _| {}).unwrap()
        },
    );
    // `correct`'s threads in blocks of 8, 16 and 32 bricks (the adapter picks 8 or 16): list
    // counts that are not whole blocks leave a last block part empty.
    for n in [8, 16, 32] {
        same_on_both(
            &format!("blocks of {n} bricks"),
            &a,
            &params,
            &gpu,
            Default::default(),
            |s| {
                s.set_block_bricks(n);
                s.synthesize(b, &|_, _| {}).unwrap()
            },
        );
    }
    // A tileable solid (reads wrap around each level's period; periodic jitter and tiling).
    let params = SynthParams {
        seed: 5,
        ..Default::default()
    };
    same_on_both("tileable", &a, &params, &gpu, Default::default(), |s| {
        s.synthesize_tileable(32, &|_, _| {}, false).unwrap().0
    });
    // The same tileable solid in groups of 16^3 (boxes of the periodic solid with their
    // padding, initial level wrapping): what a solid too large for one buffer goes through.
    let in_groups = SynthOptions {
        max_group: Some(16),
        shared_coarse_levels: Some(false),
        ..Default::default()
    };
    same_on_both("tileable in groups", &a, &params, &gpu, in_groups, |s| {
        s.synthesize_tileable(32, &|_, _| {}, false).unwrap().0
    });
    // One colour source per channel, the matched table among them, on three different
    // exemplars (each channel's pixel from its own exemplar's data).
    let three = analysis(true, Border::Wrap);
    let params = SynthParams {
        seed: 4,
        color: "z,matched,x".parse().unwrap(),
        ..Default::default()
    };
    let b = Box3::new([-5, -1, 2], [6, 8, 9]);
    same_on_both(
        "per-channel colours",
        &three,
        &params,
        &gpu,
        Default::default(),
        |s| s.synthesize(b, &|_, _| {}).unwrap(),
    );
    // The coarse-level cache: level L-1 built once from a tileable solid, uploaded per request.
    let params = SynthParams {
        seed: 8,
        coarse_cache: Some(64),
        ..Default::default()
    };
    let b = Box3::new([-6, 2, -9], [6, 10, 3]);
    same_on_both("coarse cache", &a, &params, &gpu, Default::default(), |s| {
        s.synthesize(b, &|_, _| {}).unwrap()
    });
    // Once the cache is built (or a request's shared coarse levels are done) the GPU releases
    // the pipelines only the coarse levels use: a later request of the session that corrects
    // those levels again (a tileable volume, which does not read the cache; a box in groups)
    // builds them again. After the cache the GPU releases the coarse levels' candidate tables
    // too (the CPU its prepared tables), and a tileable volume builds them again from the level
    // data on the device (checked below).
    same_on_both(
        "coarse levels corrected again after a release",
        &a,
        &params,
        &gpu,
        Default::default(),
        |s| {
            let mut v = s.synthesize(b, &|_, _| {}).unwrap();
            let t = s.synthesize_tileable(32, &|_, _| {}, false).unwrap().0;
            v.data.extend_from_slice(&t.data);
            v
        },
    );
    for compute in [&Compute::Cpu, &gpu] {
        let mut s = Synthesizer::new(&a, params.clone(), compute).unwrap();
        s.synthesize(b, &|_, _| {}).unwrap();
        assert_eq!(
            s.tables_held(),
            [false, false, false, true],
            "after the cache"
        );
        s.synthesize_tileable(32, &|_, _| {}, false).unwrap();
        assert_eq!(s.tables_held(), [true; 4], "after a tileable request");
    }
    let params = SynthParams {
        seed: 9,
        ..Default::default()
    };
    // (Not shared by default on a GPU with its own memory.)
    let shared = SynthOptions {
        max_group: Some(16),
        shared_coarse_levels: Some(true),
        ..Default::default()
    };
    same_on_both(
        "shared coarse levels, twice",
        &a,
        &params,
        &gpu,
        shared,
        |s| {
            let mut v = s
                .synthesize(Box3::new([-9, -3, 0], [20, 12, 24]), &|_, _| {})
                .unwrap();
            let w = s
                .synthesize(Box3::new([3, -20, -4], [30, 1, 9]), &|_, _| {})
                .unwrap();
            v.data.extend_from_slice(&w.data);
            v
        },
    );
}

/// Spatial determinism on the GPU backend itself (the CPU backend's is tested in
/// tests/synthesis/determinism.rs, and GPU = CPU above): seeded random boxes, on negative
/// coordinates and across brick boundaries as they fall, equal the same voxels of a larger box, and
/// the larger box synthesized in groups (seams every 12 voxels, each group with its own dependency
/// padding) equals the box in one piece.
#[test]
fn gpu_boxes_are_windows_of_larger_gpu_boxes() {
    let _serial = crate::serial();
    let Some(gpu) = gpu_backend() else { return };
    let a = analysis(false, Border::Wrap);
    let params = SynthParams {
        seed: 21,
        ..Default::default()
    };
    let synth = |b: Box3, max_group: Option<u32>| {
        // Each group's own coarse levels (shared ones below).
        let options = SynthOptions {
            max_group,
            shared_coarse_levels: max_group.map(|_| false),
            ..Default::default()
        };
        let mut s = Synthesizer::with_options(&a, params.clone(), &gpu, options).unwrap();
        s.synthesize(b, &|_, _| {}).unwrap()
    };
    let big = Box3::new([-9, -6, -7], [9, 10, 5]);
    let whole = synth(big, None);
    let mut rng = solidsynth::util::hash::SeededRng::new(19);
    for _ in 0..6 {
        let lo = [0, 1, 2].map(|i| big.lo[i] + rng.below((big.hi[i] - big.lo[i]) as u64) as i32);
        let hi = [0, 1, 2].map(|i| (lo[i] + 1 + rng.below(7) as i32).min(big.hi[i]));
        let small = Box3::new(lo, hi);
        let part = synth(small, None);
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                for x in lo[0]..hi[0] {
                    let at = |v: &solidsynth::volume::Volume, b: Box3| {
                        v.at(
                            (x - b.lo[0]) as u32,
                            (y - b.lo[1]) as u32,
                            (z - b.lo[2]) as u32,
                        )
                        .to_vec()
                    };
                    assert_eq!(
                        at(&part, small),
                        at(&whole, big),
                        "voxel ({x},{y},{z}) of {small:?} differs inside {big:?}"
                    );
                }
            }
        }
    }
    let grouped = synth(big, Some(12));
    words_equal(
        "grouped on the GPU",
        &bytes_to_words(&whole.data),
        &bytes_to_words(&grouped.data),
    )
    .unwrap();
    // The same groups sharing their coarse levels: each level above the finest synthesized
    // once (itself in groups), its triples read back and uploaded as the groups' parents.
    let mut s = Synthesizer::with_options(
        &a,
        params.clone(),
        &gpu,
        SynthOptions {
            max_group: Some(12),
            shared_coarse_levels: Some(true),
            ..Default::default()
        },
    )
    .unwrap();
    let shared = s.synthesize(big, &|_, _| {}).unwrap();
    assert!(s.last_stats().unwrap().groups > 1);
    words_equal(
        "grouped, coarse levels shared, on the GPU",
        &bytes_to_words(&whole.data),
        &bytes_to_words(&shared.data),
    )
    .unwrap();
    // The same requests reading each group's colours back while the next group runs (the
    // default on a GPU of its own memory only, forced here): with their own and with shared
    // coarse levels.
    for shared_levels in [false, true] {
        let mut s = Synthesizer::with_options(
            &a,
            params.clone(),
            &gpu,
            SynthOptions {
                max_group: Some(12),
                shared_coarse_levels: Some(shared_levels),
                overlapped_reads: Some(true),
                ..Default::default()
            },
        )
        .unwrap();
        let overlapped = s.synthesize(big, &|_, _| {}).unwrap();
        let groups = s.last_stats().unwrap().groups;
        assert!(groups > 1);
        assert_eq!(
            s.overlapped_hand_overs(),
            groups - 1,
            "groups handed over late"
        );
        words_equal(
            &format!("grouped, reads overlapped, coarse levels shared: {shared_levels}"),
            &bytes_to_words(&whole.data),
            &bytes_to_words(&overlapped.data),
        )
        .unwrap();
    }
    // With the coarse cache, handed over group by group (a surface's path), against the CPU
    // backend's groups.
    let cached = SynthParams {
        coarse_cache: Some(64),
        ..params.clone()
    };
    let by_group = |compute: &Compute| {
        let mut s = Synthesizer::with_options(
            &a,
            cached.clone(),
            compute,
            SynthOptions {
                max_group: Some(12),
                overlapped_reads: Some(true),
                ..Default::default()
            },
        )
        .unwrap();
        let mut bricks = Vec::new();
        let mut colors = Vec::new();
        let requested = solidsynth::lazy::bricks::bricks_of_box(big);
        s.synthesize_bricks_by_group(&requested, &|_, _| {}, |group| {
            bricks.extend(group.bricks);
            colors.extend(group.colors);
            Ok(())
        })
        .unwrap();
        let groups = s.last_stats().unwrap().groups;
        assert!(groups > 1);
        // (The CPU backend never overlaps its reads.)
        let overlapped = if matches!(compute, Compute::Cpu) {
            0
        } else {
            groups - 1
        };
        assert_eq!(
            s.overlapped_hand_overs(),
            overlapped,
            "groups handed over late"
        );
        (bricks, colors)
    };
    let (cpu_bricks, cpu_colors) = by_group(&Compute::Cpu);
    let (gpu_bricks, gpu_colors) = by_group(&gpu);
    assert_eq!(cpu_bricks, gpu_bricks, "groups' bricks");
    words_equal("cached groups, reads overlapped", &cpu_colors, &gpu_colors).unwrap();
}

/// The GPU backend for a synthesizer; None (the test is skipped) where there is no adapter,
/// which fails instead under CI (`crate::gpu`).
fn gpu_backend() -> Option<Compute> {
    crate::gpu()?;
    Some(Compute::open(BackendChoice::Gpu, &GpuOptions::from_env()).unwrap())
}

/// Run `f` on a fresh synthesizer of each backend and require byte-identical volumes.
fn same_on_both(
    what: &str,
    a: &solidsynth::analysis::Analysis,
    params: &SynthParams,
    gpu: &Compute,
    options: SynthOptions,
    f: impl Fn(&mut Synthesizer) -> solidsynth::volume::Volume,
) {
    let with = |compute: &Compute| {
        Synthesizer::with_options(a, params.clone(), compute, options.clone()).unwrap()
    };
    let on_cpu = f(&mut with(&Compute::Cpu));
    let on_gpu = f(&mut with(gpu));
    words_equal(
        what,
        &bytes_to_words(&on_cpu.data),
        &bytes_to_words(&on_gpu.data),
    )
    .unwrap();
}

fn bytes_to_words(b: &[u8]) -> Vec<u32> {
    b.chunks(4)
        .map(|c| {
            c.iter()
                .enumerate()
                .fold(0u32, |w, (i, &x)| w | (x as u32) << (8 * i))
        })
        .collect()
}

/// A warm GPU cut session keeps its buffers from one cut to the next (`CutSession`): cuts of
/// other sizes and orientations in between must leave every cut's bytes those of the CPU
/// backend's session, whatever the reused buffers held before.
#[test]
fn warm_gpu_cut_session_repeats_its_cuts_exactly() {
    use solidsynth::lazy::cut::{CutSession, CutSpec};
    let _serial = crate::serial();
    let Some(gpu) = gpu_backend() else { return };
    let a = analysis(false, Border::Wrap);
    let params = SynthParams {
        seed: 21,
        coarse_cache: Some(64),
        ..Default::default()
    };
    let axis = CutSpec {
        origin: [-7.0, 12.0, 30.5],
        normal: [0.0, 0.0, 1.0],
        up: None,
        size: 24,
        spacing: 1.0,
    };
    let oblique = CutSpec {
        origin: [5.0, -3.0, 9.0],
        normal: [0.3, 0.5, 0.8],
        up: None,
        size: 16,
        spacing: 1.5,
    };
    let mut on_cpu = CutSession::new(Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap());
    let mut on_gpu = CutSession::new(Synthesizer::new(&a, params, &gpu).unwrap());
    for (i, spec) in [&axis, &oblique, &axis, &oblique, &axis]
        .into_iter()
        .enumerate()
    {
        let cpu = on_cpu.cut(spec).unwrap();
        let gpu = on_gpu.cut(spec).unwrap();
        assert!(
            cpu.pixels == gpu.pixels,
            "cut {i} ({:?}) differs between the warm sessions",
            spec.normal
        );
    }
}
