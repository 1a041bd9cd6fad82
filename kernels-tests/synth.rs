//! Kernels `init`, `upsample`, `correct`, `colorize`: GPU and CPU bit-exact, on states built from
//! a real analysis (random states would not exercise the candidate logic), in boxes with negative
//! coordinates, for both candidate modes, shared and three-exemplar analyses, wrap and mirror.

use crate::compare::words_equal;
use solidsynth::analysis::{Analysis, AnalysisInput, AnalysisParams};
use solidsynth::backend::{BackendChoice, Compute};
use solidsynth::exemplar::{decode_image, Border};
use solidsynth::gpu::GpuOptions;
use solidsynth::lazy::{
    Box3, CandidateMode, ColorSource, SynthOptions, SynthParams, Synthesizer,
};

fn fixture(bytes: &[u8]) -> solidsynth::exemplar::Image {
    decode_image(bytes, "fixture").unwrap()
}

fn analysis(three: bool, border: Border) -> Analysis {
    let cells = fixture(include_bytes!("../tests/fixtures/cells32.png"));
    let marble = fixture(include_bytes!("../tests/fixtures/marble32.png"));
    let exemplars = if three {
        vec![cells.clone(), marble, cells]
    } else {
        vec![cells]
    };
    let a = analyze(exemplars, vec![], border);
    // The default analysis balances usage: the kernels then scale distances by penalties.
    assert!(
        a.exemplars
            .iter()
            .all(|e| e.levels.iter().any(|l| l.penalty.iter().any(|&p| p > 0))),
        "the kernels must be tested with usage penalties"
    );
    a
}

/// The default analysis (on the CPU) of `exemplars` with feature masks `masks`.
fn analyze(
    exemplars: Vec<solidsynth::exemplar::Image>,
    masks: Vec<solidsynth::exemplar::Image>,
    border: Border,
) -> Analysis {
    let names = (0..exemplars.len())
        .map(|i| format!("fixture {i}"))
        .collect();
    let input = AnalysisInput {
        exemplars,
        masks,
        border,
        names,
    };
    solidsynth::lazy::analyze(
        &input,
        &AnalysisParams::default(),
        &Compute::Cpu,
        &|_, _| {},
    )
    .unwrap()
}

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
    // A one-voxel-thick slab (an axis-aligned cut's request): its bricks and their padding.
    // (Until session 25 it was planned voxel by voxel, with partial brick masks; passes now
    // compute whole bricks, so every mask is full.)
    let a = analysis(false, Border::Wrap);
    let params = SynthParams {
        seed: 78,
        ..Default::default()
    };
    let thin = Box3::new([-6, 1, 5], [13, 22, 6]);
    same_on_both("one-voxel-thick slab", &a, &params, &gpu, Default::default(), |s| {
        s.synthesize(thin, &|_, _| {}).unwrap()
    });
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
        same_on_both(&format!("feature, rgba={rgba}"), &a, &params, &gpu, Default::default(), |s| {
            s.synthesize(b, &|_, _| {}).unwrap()
        });
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
            same_on_both("feature, rgba, per channel", &a, &params, &gpu, Default::default(), |s| {
                s.synthesize(b, &|_, _| {}).unwrap()
            });
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
        same_on_both(&format!("odd size, {border:?}"), &a, &params, &gpu, Default::default(), |s| {
            s.synthesize(b, &|_, _| {}).unwrap()
        });
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
    same_on_both("weights beyond 16 bits", &a, &params, &gpu, Default::default(), |s| {
        s.synthesize(b, &|_, _| {}).unwrap()
    });
    let a = analysis(false, Border::Wrap);
    // A parameter arena of 1 KiB (a few dispatches): each level's batch is submitted in parts,
    // whenever the arena is full.
    let params = SynthParams {
        seed: 13,
        ..Default::default()
    };
    same_on_both("small parameter arena", &a, &params, &gpu, Default::default(), |s| {
        s.set_parameter_arena_bytes(1024).unwrap();
        s.synthesize(b, &|_, _| {}).unwrap()
    });
    // `correct`'s threads in blocks of 8, 16 and 32 bricks (the adapter picks 8 or 16): list
    // counts that are not whole blocks leave a last block part empty.
    for n in [8, 16, 32] {
        same_on_both(&format!("blocks of {n} bricks"), &a, &params, &gpu, Default::default(), |s| {
            s.set_block_bricks(n);
            s.synthesize(b, &|_, _| {}).unwrap()
        });
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
    same_on_both("per-channel colours", &three, &params, &gpu, Default::default(), |s| {
        s.synthesize(b, &|_, _| {}).unwrap()
    });
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
    same_on_both("shared coarse levels, twice", &a, &params, &gpu, shared, |s| {
        let mut v = s
            .synthesize(Box3::new([-9, -3, 0], [20, 12, 24]), &|_, _| {})
            .unwrap();
        let w = s
            .synthesize(Box3::new([3, -20, -4], [30, 1, 9]), &|_, _| {})
            .unwrap();
        v.data.extend_from_slice(&w.data);
        v
    });
}

/// Spatial determinism on the GPU backend itself (the CPU backend's is tested in
/// tests/synthesis.rs, and GPU = CPU above): seeded random boxes, on negative coordinates and
/// across brick boundaries as they fall, equal the same voxels of a larger box, and the larger box
/// synthesized in groups (seams every 12 voxels, each group with its own dependency padding)
/// equals the box in one piece.
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
    let mut s = Synthesizer::with_options(&a, params.clone(), &gpu, SynthOptions { max_group: Some(12), shared_coarse_levels: Some(true), ..Default::default() }).unwrap();
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
        let mut s = Synthesizer::with_options(&a, params.clone(), &gpu, SynthOptions { max_group: Some(12), shared_coarse_levels: Some(shared_levels), overlapped_reads: Some(true), ..Default::default() }).unwrap();
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
        let mut s = Synthesizer::with_options(&a, cached.clone(), compute, SynthOptions { max_group: Some(12), overlapped_reads: Some(true), ..Default::default() }).unwrap();
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

/// Single kernels in isolation: each GPU kernel against its CPU reference on the same inputs.
#[test]
fn each_synthesis_kernel_matches_its_reference() {
    let _serial = crate::serial();
    let Some(_) = crate::gpu() else { return };
    use solidsynth::contract::uniforms::{InitParams, UpsampleParams};
    use solidsynth::lazy::{jitter, pack::LevelPack};
    let a = analysis(false, Border::Wrap);
    let pack = LevelPack::new(&a, 3);
    let o = &pack.offsets;
    let table = jitter::table();
    let amps = jitter::amplitudes(3.0);
    let sig = jitter::sigma2_fixed();
    // The parent level: the bricks of a box straddling zero, in a shuffled order (slots need not
    // be sorted).
    use solidsynth::lazy::bricks;
    let mut parent_bricks =
        bricks::bricks_of_box(solidsynth::lazy::Box3::new([-9, -2, 5], [2, 4, 12]));
    parent_bricks.reverse();
    let parent_grid = bricks::BrickGrid::new(&parent_bricks);
    let mut parent_index = parent_grid.table.clone();
    let parent_list = bricks::push_list(&mut parent_index, &parent_bricks);
    let count = parent_bricks.len() as u32;
    let init = InitParams {
        list_offset: parent_list,
        list_count: count,
        grid_stride: solidsynth::gpu::context::dispatch_grid(count * 64).2,
        ex_width: pack.width,
        ex_height: pack.height,
        border: 0,
        seed_lo: 0xDEAD,
        seed_hi: 3,
        jitter_on: 1,
        tile_x: 2,
        tile_y: 1,
        tile_z: 0,
        slab_offset: o.slab,
        amp0: amps[0],
        amp1: amps[1],
        amp2: amps[2],
        amp3: amps[3],
        sig0: sig[0],
        sig1: sig[1],
        sig2: sig[2],
        sig3: sig[3],
        channels: pack.channels,
        pixel_words: pack.pixel_words,
        pixels0: o.pixels[0],
        pixels1: o.pixels[1],
        pixels2: o.pixels[2],
        ..Default::default()
    };
    let cpu_init = solidsynth::cpu::init::init(&init, &table, &pack.words, &parent_index, &[]);
    let ctx = solidsynth::gpu::GpuContext::new(&GpuOptions::from_env()).unwrap();
    let mut g =
        solidsynth::gpu::synth::GpuSynth::new(std::sync::Arc::new(ctx), &[pack.clone()], &table)
            .unwrap();
    let gpu_parent_index = g.upload_index(&parent_index);
    let gpu_state = g.init(0, &init, &gpu_parent_index, None).unwrap();
    words_equal("init", &cpu_init, &g.read_state(&gpu_state).unwrap()).unwrap();
    // The jitter moves voxels: with it off, the same box differs.
    let flat = solidsynth::cpu::init::init(
        &InitParams {
            jitter_on: 0,
            ..init
        },
        &table,
        &pack.words,
        &parent_index,
        &[],
    );
    assert!(words_equal("jitter matters", &cpu_init, &flat).is_err());
    // Level L-1 from the coarse-level cache: the same bricks read from a periodic cube of
    // triples (valid coordinates of this level) at the warped position plus the tile offset.
    let n = 8u32;
    let cache: Vec<u32> = (0..n.pow(3) * 3)
        .map(|i| {
            let h = solidsynth::util::hash::hash32(i ^ 0xCAC4E);
            solidsynth::analysis::frame::pack(h % pack.width, (h >> 16) % pack.height)
        })
        .collect();
    let cached = InitParams {
        cache_period: n,
        tile_x: 5,
        tile_y: 1,
        tile_z: 7,
        ..init
    };
    let cpu_cached =
        solidsynth::cpu::init::init(&cached, &table, &pack.words, &parent_index, &cache);
    let gpu_cache = g.upload_index(&cache);
    let gpu_cached = g
        .init(0, &cached, &gpu_parent_index, Some(&gpu_cache))
        .unwrap();
    words_equal(
        "init from the cache",
        &cpu_cached,
        &g.read_state(&gpu_cached).unwrap(),
    )
    .unwrap();
    assert!(words_equal("the cache is read", &cpu_init, &cpu_cached).is_err());

    // Upsampling into a child box (the same level's data serves for the values).
    // The child bricks: some of the parents' children, and one whose parent is absent (reads as
    // coordinate 0 on both backends).
    let mut child_bricks =
        bricks::bricks_of_box(solidsynth::lazy::Box3::new([-17, -3, 11], [3, 6, 14]));
    child_bricks.push([40, 40, 40]);
    let child_grid = bricks::BrickGrid::new(&child_bricks);
    let mut child_index = child_grid.table.clone();
    let child_list = bricks::push_list(&mut child_index, &child_bricks);
    let parent_table = child_index.len() as u32;
    child_index.extend_from_slice(&parent_grid.table);
    let count = child_bricks.len() as u32;
    let up = UpsampleParams {
        parent_grid_lo_x: parent_grid.lo[0],
        parent_grid_lo_y: parent_grid.lo[1],
        parent_grid_lo_z: parent_grid.lo[2],
        parent_grid_x: parent_grid.dims[0],
        parent_grid_y: parent_grid.dims[1],
        parent_grid_z: parent_grid.dims[2],
        parent_table,
        list_offset: child_list,
        list_count: count,
        grid_stride: solidsynth::gpu::context::dispatch_grid(count * 64).2,
        ex_width: pack.width,
        ex_height: pack.height,
        border: 0,
        channels: pack.channels,
        pixel_words: pack.pixel_words,
        pixels0: o.pixels[0],
        pixels1: o.pixels[1],
        pixels2: o.pixels[2],
        ..Default::default()
    };
    let cpu_up = solidsynth::cpu::upsample::upsample(&up, &pack.words, &cpu_init, &child_index);
    let gpu_child_index = g.upload_index(&child_index);
    let gpu_up = g.upsample(0, &up, gpu_state, &gpu_child_index).unwrap();
    words_equal("upsample", &cpu_up, &g.read_state(&gpu_up).unwrap()).unwrap();
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
