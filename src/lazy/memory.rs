//! Memory estimates of requests, made before anything is allocated for them, so a request that
//! cannot fit is refused with its estimate instead of failing part way. The numbers are upper
//! bounds of the working sets the synthesizer's grouping actually holds.

/// The default group edge of boxes, tileable solids and surfaces where the backend's memory is
/// the host's (the CPU backend, a software or integrated GPU): measured on the CPU backend of a
/// 2-core Xeon, `synth --size 256` took 12.5 s and 468 MB in one group, 12.7 s and 153 MB in
/// groups of 128; the bunny's surface at 1024 33 s either way, 451 or 240 MB; on lavapipe 256^3
/// 30.6 s either way, 594 or 441 MB. A discrete GPU keeps its own memory and runs fewer, larger
/// dispatches best. Cuts keep one group: small already, and grouping slowed them (CPU backend,
/// 256^2 with the paper's passes: 655 -> 715 ms).
pub const HOST_MEMORY_GROUP: u32 = 128;

/// The largest group edge at the finest level: the whole group without `--max-group`.
pub const LARGEST_GROUP: u32 = 512;

/// Padding per side assumed when sizing chunks (the plan's exact padding is at most this).
pub const PADDING_ESTIMATE: u32 = 14;

/// Bytes of working memory one chunk of `side`^3 needs at the finest level, at most: two
/// state buffers of the padded box (the GPU's state and its pass-start copy; the CPU
/// backend holds one), each voxel a triple and a value word (one word covers up to four
/// channels; the estimate assumes that).
pub fn chunk_bytes(side: u32) -> u64 {
    super::grouping::padded_state_bytes([side as u64; 3]).saturating_mul(2)
}

/// The largest group side, in its own level's voxels, at `coarser_by` levels above the finest,
/// given the finest level's cap `max_chunk_side` (`--max-group`; None: [`LARGEST_GROUP`]); `whole_box`: the
/// level's request is every brick of a box.
///
/// Without a cap, a coarse level's 512 halves per level, so that its groups span the same space
/// as the finest level's. With one, a shared coarse level's groups take the cap in their own
/// voxels (twice the space per level, an eighth of the voxels), and a box's a quarter more, in
/// whole bricks: a box's coarse level is the finest groups' parents with their padding, a
/// little more than the cap whenever the finest groups are (256^3 in groups of 128: 136 voxels
/// at the level above). Cut at exactly the cap, that request took one group of 128 and seven
/// slivers of 8, each recomputing a whole padding: 1.35 times the voxels of one group of 136
/// (lavapipe, 256^3: 20.4 / 21.1 / 19.8 s against 22.5 / 22.5 / 21.6 s, the largest state
/// 107 against 91 MiB; BENCHMARKS.md). A surface's coarse levels keep the cap:
/// their cubes are not slivers, and larger ones held the bunny's 1024 at 430 MB against 367.
pub fn group_cap(max_chunk_side: Option<u32>, coarser_by: usize, whole_box: bool) -> u32 {
    match max_chunk_side {
        None => LARGEST_GROUP >> coarser_by,
        Some(side) if coarser_by == 0 || !whole_box => side.min(LARGEST_GROUP),
        Some(side) => ((side + side / 4) / 4 * 4).max(side).min(LARGEST_GROUP),
    }
}

/// Bytes of the coarse-level cache when one is asked for (`--coarse-cache N`): its build (a
/// tileable state of period N/2, two copies on a GPU) and the triples it keeps, copied once per
/// group.
pub fn coarse_cache_bytes(coarse_cache: Option<u32>) -> u64 {
    coarse_cache.map_or(0, |n| {
        let voxels = (n as u64 / 2).pow(3);
        voxels * (16 * 2 + 12 * 2)
    })
}

/// Bytes of the shared coarse levels ([`super::SynthOptions::shared_coarse_levels`]) of a
/// request of `finest_voxels` finest-level voxels (padding included) whose groups' working sets
/// are `group_working` bytes: held only when the request takes several groups, counted whenever
/// it may (without the coarse cache), so also for a GPU with its own memory, which does not
/// share them (the estimate runs before the device is opened: an over-estimate there of about
/// 2 bytes per voxel). The parent level's triples (6 or, for exemplars over 512 pixels, 12
/// bytes per voxel, an eighth of the finest voxels, and the level below it while it is built:
/// at most 1.7 bytes per finest voxel, 2 with the padding) and one group's parent state built on
/// the host (an eighth of its voxels, one copy: a sixteenth of its working set).
pub fn shared_levels_bytes(
    coarse_cache: Option<u32>,
    finest_voxels: u64,
    group_working: u64,
) -> u64 {
    if coarse_cache.is_some() {
        return 0;
    }
    finest_voxels.saturating_mul(2).saturating_add(group_working / 16)
}

/// Working bytes of the largest group of a shared coarse level of a request whose largest side
/// is `largest` finest voxels, in finest groups of `group`: such a group may exceed the finest
/// group's side by a quarter ([`group_cap`]), and holds at most the parents of the whole request
/// and their padding. Zero where no level is shared (one group, or the coarse cache).
pub fn coarse_group_bytes(coarse_cache: Option<u32>, group: u32, largest: u32) -> u64 {
    if coarse_cache.is_some() || largest <= group {
        return 0;
    }
    let parents = largest.div_ceil(2) + PADDING_ESTIMATE;
    chunk_bytes(group_cap(Some(group), 1, true).min(parents))
}

/// Working bytes of the synthesis of a box of `size` voxels in groups of edge `group` (at most
/// the box's largest side): one group's working set or a shared coarse level's largest group,
/// the coarse cache and the shared levels. The caller adds what its outputs hold.
pub fn box_working_bytes(size: [u64; 3], group: u32, coarse_cache: Option<u32>) -> u64 {
    // (Saturating throughout: the estimate of an absurd box stays absurd, so it is refused.)
    let largest = size.into_iter().max().unwrap_or(0).min(u32::MAX as u64) as u32;
    let group = group.min(largest);
    let padded: u64 = size.iter().fold(1u64, |voxels, &d| {
        voxels.saturating_mul(d.saturating_add(2 * PADDING_ESTIMATE as u64))
    });
    let working = chunk_bytes(group);
    working
        .max(coarse_group_bytes(coarse_cache, group, largest))
        .saturating_add(coarse_cache_bytes(coarse_cache))
        .saturating_add(shared_levels_bytes(coarse_cache, padded, working))
}

/// Working bytes of a sparse request (a cut, a surface's shell) of `bricks` requested 4^3-voxel
/// bricks spread over a surface `extent` voxels wide, in groups of edge `group_side`: the
/// requested bricks' colours and bookkeeping, one group's working set (the group's bricks with
/// their dependency padding, at most a dense padded cube), the coarse cache and the shared
/// levels. The caller adds what its outputs hold.
pub fn sparse_working_bytes(
    bricks: u64,
    extent: f64,
    group_side: u32,
    coarse_cache: Option<u32>,
) -> u64 {
    // Per requested brick: 64 colours and its list and lookup entries.
    let requested = bricks.saturating_mul(256 + 32);
    // A group is a cube of the request: on a surface it holds about (side / extent)^2 of the
    // bricks, and stores their padding too, about eight times their voxels at the finest
    // level (6 to 9 voxels of padding around a 4-voxel brick layer, 4 more with `--color
    // fitted`, whose colours read the next bricks; so this over-estimates or meets it; the
    // coarser levels halving), 16 bytes a voxel, two copies (the GPU's state and its
    // pass-start copy; the CPU holds one).
    let share = (group_side as f64 / extent.max(1.0)).powi(2).min(1.0);
    let group_bricks = ((bricks as f64 * share) as u64).min((group_side as u64 / 4).pow(3));
    let working = chunk_bytes(group_side).min(group_bricks * 64 * 16 * 2 * 8);
    // Shared coarse levels: the stored finest voxels, about eight per requested voxel.
    let shared = shared_levels_bytes(coarse_cache, bricks.saturating_mul(64 * 8), working);
    requested
        .saturating_add(working)
        .saturating_add(coarse_cache_bytes(coarse_cache))
        .saturating_add(shared)
}
