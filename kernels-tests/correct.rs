//! Kernel `correct` alone: one correction pass (the eight parity-class sub-passes) over the
//! bricks of a box, from a state made by the CPU `init`, against the CPU reference, which runs
//! it both sub-pass by sub-pass against a pass-start copy (the shader's order) and brick by brick
//! in place (the CPU backend's fast path). Both candidate modes, a shared and a three-exemplar
//! analysis, wrap and mirror borders.

use crate::compare::words_equal;
use crate::synth_inputs::{analysis, gpu_synth, initial_state, BoxBricks};
use solidsynth::contract::level::LevelPack;
use solidsynth::contract::uniforms::CorrectParams;
use solidsynth::cpu::correct::{correct_pass, Prepared};
use solidsynth::exemplar::Border;
use solidsynth::lazy::{kernel_params, Box3, CandidateMode, SUBPASS_ORDER};

/// The sub-passes of one pass over every class voxel of every brick of `bricks`, whose masks
/// (one byte per listed brick, every bit set) are appended to its index.
fn full_pass(
    pack: &LevelPack,
    border: Border,
    mode: CandidateMode,
    bricks: &mut BoxBricks,
) -> Vec<CorrectParams> {
    let mask_offset = bricks.index.len() as u32;
    let words = bricks.count().div_ceil(4) as usize;
    bricks.index.extend(std::iter::repeat_n(u32::MAX, words));
    SUBPASS_ORDER
        .iter()
        .map(|&class| CorrectParams {
            mask_offset,
            ..kernel_params::correct_params(
                pack,
                &bricks.grid,
                (bricks.list, bricks.count()),
                class,
                // The GPU executor of one pack treats it as the finest level.
                pack.k3d_used(true),
                border.code(),
                mode,
            )
        })
        .collect()
}

#[test]
fn correct_matches_its_reference_and_its_comparison_can_fail() {
    let _serial = crate::serial();
    let cases = [
        (false, Border::Wrap, CandidateMode::ThreeD, 1),
        (true, Border::Mirror, CandidateMode::ThreeD, 2),
        (false, Border::Mirror, CandidateMode::TwoD, 0),
    ];
    for (three, border, mode, level) in cases {
        let what =
            format!("correct ({mode:?}, three exemplars {three}, {border:?}, level {level})");
        let a = analysis(three, border);
        let pack = LevelPack::new(&a, level);
        let Some(mut g) = gpu_synth(&pack) else {
            return;
        };
        let mut bricks = BoxBricks::of(Box3::new([-9, -6, 3], [7, 6, 15]));
        let (state, _) = initial_state(&pack, border, &bricks);
        let ps = full_pass(&pack, border, mode, &mut bricks);
        let prepared = Prepared::new(&ps[0], &pack.words);
        let mut reference = state.clone();
        correct_pass(
            &prepared,
            &ps,
            &pack.words,
            &mut reference,
            &mut Vec::new(),
            &bricks.index,
            false,
        );
        let mut in_place = state.clone();
        correct_pass(
            &prepared,
            &ps,
            &pack.words,
            &mut in_place,
            &mut Vec::new(),
            &bricks.index,
            true,
        );
        words_equal(&format!("{what}: CPU in place"), &reference, &in_place).unwrap();
        assert!(
            words_equal(&what, &state, &reference).is_err(),
            "{what}: the pass changes the state"
        );

        let index = g.upload_index(&bricks.index);
        let mut s = g.upload_state(&state);
        g.correct_pass(0, &ps, &mut s, &index).unwrap();
        let on_gpu = g.read_state(&s).unwrap();
        words_equal(&what, &reference, &on_gpu).unwrap();

        // The comparison fails on a perturbed output (a triple's low bit)...
        let mut perturbed = on_gpu.clone();
        perturbed[on_gpu.len() / 3] ^= 1;
        assert!(words_equal(&what, &reference, &perturbed).is_err());
        // ... and on a kernel run that skips a class: the pass without its last sub-pass.
        let mut short = g.upload_state(&state);
        g.correct_pass(0, &ps[..ps.len() - 1], &mut short, &index)
            .unwrap();
        let short = g.read_state(&short).unwrap();
        assert!(
            words_equal(&what, &reference, &short).is_err(),
            "{what}: a skipped class goes unnoticed"
        );
    }
}
