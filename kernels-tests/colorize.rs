//! Kernel `colorize` alone: the colours of a state's voxels (made by the CPU `init`) from each
//! colour source (the voxel's cached mean, each exemplar's pixel, the matched table, the fitted
//! weighting, which reads neighbours, also wrapped into a period), against the CPU reference.

use crate::compare::words_equal;
use crate::synth_inputs::{analysis, gpu_synth, initial_state, BoxBricks};
use solidsynth::contract::level::LevelPack;
use solidsynth::exemplar::Border;
use solidsynth::lazy::{kernel_params, Box3};

#[test]
fn colorize_matches_its_reference_and_its_comparison_can_fail() {
    let _serial = crate::serial();
    let a = analysis(true, Border::Mirror);
    let mut pack = LevelPack::new(&a, 0);
    // A matched table that is not the identity, so reading it shows.
    let at = pack.offsets.color_match as usize;
    for (i, w) in pack.words[at..at + 256].iter_mut().enumerate() {
        *w = (255 - i as u32) * 0x0001_0101;
    }
    let Some(mut g) = gpu_synth(&pack) else {
        return;
    };
    let bricks = BoxBricks::of(Box3::new([-6, -3, -9], [10, 9, 3]));
    let (state, _) = initial_state(&pack, Border::Mirror, &bricks);
    let index = g.upload_index(&bricks.index);
    let s = g.upload_state(&state);
    // Per channel, 4 bits of source: 0 the cached mean, a + 1 exemplar a's pixel, 4 matched,
    // 5 fitted; with a period of 8 the fitted reads (and the voxels) wrap into [0, 8)^3.
    let mut outputs = Vec::new();
    for (source, period) in [
        (0x000, 0),
        (0x123, 0),
        (0x321, 0),
        (0x444, 0),
        (0x041, 0),
        (0x555, 0),
        (0x505, 0),
        (0x555, 8),
    ] {
        let what = format!("colorize, sources {source:#05x}, period {period}");
        let p = kernel_params::colorize_params(
            &pack,
            Border::Mirror.code(),
            &bricks.grid,
            (bricks.list, bricks.count()),
            source,
            period,
        );
        let reference = solidsynth::cpu::colorize::colorize(&p, &pack.words, &state, &bricks.index);
        let read = g.colorize(0, &p, &s, &index).unwrap();
        let on_gpu = g.finish_read(read).unwrap();
        words_equal(&what, &reference, &on_gpu).unwrap();
        let mut perturbed = on_gpu.clone();
        perturbed[on_gpu.len() - 1] ^= 1 << 9;
        assert!(words_equal(&what, &reference, &perturbed).is_err());
        outputs.push(reference);
    }
    // Each source gives other colours: a kernel that ignored the source would fail above.
    for i in 0..outputs.len() {
        for j in 0..i {
            assert_ne!(outputs[i], outputs[j], "sources {i} and {j}");
        }
    }
}
