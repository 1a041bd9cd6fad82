//! What the synthesis kernels' tests share: a real analysis of the fixtures (random states would
//! not exercise the candidate logic), bricks of a box with their index, and states built by the
//! CPU references.

use solidsynth::analysis::{Analysis, AnalysisInput, AnalysisParams};
use solidsynth::backend::Compute;
use solidsynth::contract::level::LevelPack;
use solidsynth::exemplar::{decode_image, Border};
use solidsynth::lazy::{bricks, Box3};

pub fn fixture(bytes: &[u8]) -> solidsynth::exemplar::Image {
    decode_image(bytes, "fixture").unwrap()
}

pub fn analysis(three: bool, border: Border) -> Analysis {
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
pub fn analyze(
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

/// The bricks of a box, in a shuffled order (slots need not be sorted), and a brick index: the
/// bricks' table over their bounding box at word 0, then the brick list.
pub struct BoxBricks {
    pub bricks: Vec<bricks::Brick>,
    pub grid: bricks::BrickGrid,
    pub index: Vec<u32>,
    /// Word offset of the brick list in `index`.
    pub list: u32,
}

impl BoxBricks {
    pub fn of(b: Box3) -> BoxBricks {
        let mut list_bricks = bricks::bricks_of_box(b);
        list_bricks.reverse();
        let grid = bricks::BrickGrid::new(&list_bricks);
        let mut index = grid.table.clone();
        let list = bricks::push_list(&mut index, &list_bricks);
        BoxBricks {
            bricks: list_bricks,
            grid,
            index,
            list,
        }
    }

    pub fn count(&self) -> u32 {
        self.bricks.len() as u32
    }
}

/// A state of `box_bricks` at `pack`'s level, made by the CPU `init` (jitter 3, a seed with a
/// high word, the slab tiled from an offset).
pub fn initial_state(
    pack: &LevelPack,
    border: Border,
    box_bricks: &BoxBricks,
) -> (Vec<u32>, solidsynth::contract::uniforms::InitParams) {
    let mut init = solidsynth::lazy::kernel_params::init_params(
        pack,
        border.code(),
        (box_bricks.list, box_bricks.count()),
        0,
        0xDEAD | (3 << 32),
        3.0,
    );
    (init.tile_x, init.tile_y, init.tile_z) = (2, 1, 0);
    let table = solidsynth::contract::jitter::table();
    let state = solidsynth::cpu::init::init(&init, &table, &pack.words, &box_bricks.index, &[]);
    (state, init)
}

/// The GPU executor of the synthesis kernels over one level, `pack`, or None without an
/// adapter (which fails instead under CI, `crate::gpu`).
pub fn gpu_synth(pack: &LevelPack) -> Option<solidsynth::gpu::synth::GpuSynth> {
    crate::gpu()?;
    let ctx = solidsynth::gpu::GpuContext::new(&solidsynth::gpu::GpuOptions::from_env()).unwrap();
    let table = solidsynth::contract::jitter::table();
    Some(
        solidsynth::gpu::synth::GpuSynth::new(
            std::sync::Arc::new(ctx),
            std::slice::from_ref(pack),
            &table,
        )
        .unwrap(),
    )
}
