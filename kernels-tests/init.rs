//! Kernel `init` alone: the warped tiling of the candidate slab, and the same bricks read from a
//! coarse-level cache, against the CPU reference.

use crate::compare::words_equal;
use crate::synth_inputs::{analysis, gpu_synth, initial_state, BoxBricks};
use solidsynth::contract::level::LevelPack;
use solidsynth::contract::uniforms::InitParams;
use solidsynth::exemplar::Border;
use solidsynth::lazy::Box3;

#[test]
fn init_matches_its_reference() {
    let _serial = crate::serial();
    let a = analysis(false, Border::Wrap);
    let pack = LevelPack::new(&a, 3);
    let Some(mut g) = gpu_synth(&pack) else {
        return;
    };
    let table = solidsynth::contract::jitter::table();
    // A box straddling zero, its bricks listed in a shuffled order.
    let bricks = BoxBricks::of(Box3::new([-9, -2, 5], [2, 4, 12]));
    let (cpu_init, init) = initial_state(&pack, Border::Wrap, &bricks);
    let index = g.upload_index(&bricks.index);
    let state = g.init(0, &init, &index, None).unwrap();
    let gpu_init = g.read_state(&state).unwrap();
    words_equal("init", &cpu_init, &gpu_init).unwrap();
    // The comparison sees one flipped bit of the kernel's output.
    let mut perturbed = gpu_init.clone();
    perturbed[gpu_init.len() / 2] ^= 1 << 7;
    assert!(words_equal("init, perturbed", &cpu_init, &perturbed).is_err());
    // The jitter moves voxels: with it off, the same box differs.
    let flat = InitParams {
        jitter_on: 0,
        ..init
    };
    let flat = solidsynth::cpu::init::init(&flat, &table, &pack.words, &bricks.index, &[]);
    assert!(words_equal("jitter matters", &cpu_init, &flat).is_err());
    // Level L-1 from the coarse-level cache: the same bricks read from a periodic cube of
    // triples (valid coordinates of this level) at the warped position plus the tile offset.
    let n = 8u32;
    let cache: Vec<u32> = (0..n.pow(3) * 3)
        .map(|i| {
            let h = solidsynth::util::hash::hash32(i ^ 0xCAC4E);
            solidsynth::contract::triple::pack(h % pack.width, (h >> 16) % pack.height)
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
        solidsynth::cpu::init::init(&cached, &table, &pack.words, &bricks.index, &cache);
    let gpu_cache = g.upload_index(&cache);
    let gpu_cached = g.init(0, &cached, &index, Some(&gpu_cache)).unwrap();
    words_equal(
        "init from the cache",
        &cpu_cached,
        &g.read_state(&gpu_cached).unwrap(),
    )
    .unwrap();
    assert!(words_equal("the cache is read", &cpu_init, &cpu_cached).is_err());
}
