//! Kernel `upsample` alone: a child level's state inherited from a parent state (made by the
//! CPU `init`), against the CPU reference.

use crate::compare::words_equal;
use crate::synth_inputs::{analysis, gpu_synth, initial_state, BoxBricks};
use solidsynth::contract::level::LevelPack;
use solidsynth::exemplar::Border;
use solidsynth::lazy::{bricks, kernel_params, Box3};

#[test]
fn upsample_matches_its_reference() {
    let _serial = crate::serial();
    let a = analysis(false, Border::Wrap);
    // (The same level's data serves for the child's values.)
    let pack = LevelPack::new(&a, 3);
    let Some(mut g) = gpu_synth(&pack) else {
        return;
    };
    let parent = BoxBricks::of(Box3::new([-9, -2, 5], [2, 4, 12]));
    let (parent_state, _) = initial_state(&pack, Border::Wrap, &parent);
    // The child bricks: some of the parents' children, and one whose parent is absent (reads as
    // coordinate 0 on both backends).
    let mut child_bricks = bricks::bricks_of_box(Box3::new([-17, -3, 11], [3, 6, 14]));
    child_bricks.push([40, 40, 40]);
    let child_grid = bricks::BrickGrid::new(&child_bricks);
    let mut child_index = child_grid.table.clone();
    let child_list = bricks::push_list(&mut child_index, &child_bricks);
    let parent_table = child_index.len() as u32;
    child_index.extend_from_slice(&parent.grid.table);
    let up = kernel_params::upsample_params(
        &pack,
        Border::Wrap.code(),
        &parent.grid,
        parent_table,
        (child_list, child_bricks.len() as u32),
    );
    let cpu_up = solidsynth::cpu::upsample::upsample(&up, &pack.words, &parent_state, &child_index);
    let gpu_parent = g.upload_state(&parent_state);
    let gpu_child_index = g.upload_index(&child_index);
    let gpu_up = g.upsample(0, &up, gpu_parent, &gpu_child_index).unwrap();
    let gpu_up = g.read_state(&gpu_up).unwrap();
    words_equal("upsample", &cpu_up, &gpu_up).unwrap();
    let mut perturbed = gpu_up.clone();
    perturbed[3] ^= 1 << 16;
    assert!(words_equal("upsample, perturbed", &cpu_up, &perturbed).is_err());
}
