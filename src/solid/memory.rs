//! Memory estimates of requests before they run: a box, a cut or a surface's shell is refused,
//! naming the request, when its working set and its caller's outputs cannot fit in the memory
//! available (cgroup limits included), before anything is allocated for it.

use crate::backend::BackendChoice;
use crate::error::{Error, Result};
use crate::lazy::memory;
use crate::util::memory::{available_text, human_bytes};

/// The group edge a request's estimate assumes before a backend is open: `max_group` when given,
/// else the CPU backend's (host memory) group, else the largest a GPU may use (conservative).
pub fn planned_group(max_group: Option<u32>, backend: BackendChoice) -> u32 {
    max_group.unwrap_or(match backend {
        BackendChoice::Cpu => memory::HOST_MEMORY_GROUP,
        _ => memory::LARGEST_GROUP,
    })
}

/// The bytes a box of `size` voxels needs: the engine's working set in groups of edge `group`
/// (at most the box's largest side), the coarse cache (`--coarse-cache`) and `output_bytes` of
/// the caller's own outputs. Refused, naming `what`, when that exceeds the memory available.
pub fn check_box(
    what: &str,
    size: [u64; 3],
    group: u32,
    coarse_cache: Option<u32>,
    output_bytes: u64,
) -> Result<u64> {
    let largest = size.into_iter().max().unwrap_or(0).min(u32::MAX as u64) as u32;
    let group = group.min(largest);
    let estimate =
        memory::box_working_bytes(size, group, coarse_cache).saturating_add(output_bytes);
    let available = crate::util::memory::available_memory();
    if estimate > available {
        let cache = memory::coarse_cache_bytes(coarse_cache);
        let cache_note = match coarse_cache {
            Some(n) if cache > 0 => {
                format!(", of which {} for --coarse-cache {n}", human_bytes(cache))
            }
            _ => String::new(),
        };
        return Err(Error::invalid(
            what,
            format!(
                "needs about {} of memory{cache_note}, {} (a smaller --max-group bounds the \
                 working memory)",
                human_bytes(estimate),
                available_text(available)
            ),
        ));
    }
    Ok(estimate)
}

/// The 4^3-voxel bricks a square cut of `size` pixels `spacing` voxels apart crosses: its
/// plane's area over a brick face, up to sqrt(3) more for an oblique plane and a margin for its
/// edges; never more than one per pixel.
pub fn cut_bricks(size: u32, spacing: f64) -> u64 {
    let extent = size as f64 * spacing;
    let pixels = size as u64 * size as u64;
    ((extent / 4.0 + 2.0).powi(2) * 1.75).min(pixels as f64) as u64
}

/// Bytes a cut's own outputs take a pixel: the image (at most 4 channels) and the sample
/// positions (three f32).
pub const CUT_BYTES_PER_PIXEL: u64 = 16;

/// The check [`crate::Solid::cut`] makes before a cut of `spec` by a solid with these
/// `max_group` and `coarse_cache` settings, with `extra_per_pixel` bytes a pixel of the
/// caller's own (a PNG, say) beside the cut's [`CUT_BYTES_PER_PIXEL`]: a caller that queues
/// cuts runs it before queueing, so the refusal comes at once and says the same.
pub fn check_cut_request(
    spec: &crate::lazy::cut::CutSpec,
    max_group: Option<u32>,
    coarse_cache: Option<u32>,
    extra_per_pixel: u64,
) -> Result<u64> {
    check_cut(
        &format!("cut --size {} --spacing {}", spec.size, spec.spacing),
        spec.size,
        spec.spacing,
        max_group.unwrap_or(memory::LARGEST_GROUP),
        coarse_cache,
        (spec.size as u64).pow(2) * (CUT_BYTES_PER_PIXEL + extra_per_pixel),
    )
}

/// The bytes a square cut of `size` pixels `spacing` voxels apart needs in groups of edge
/// `group_side`, with `output_bytes` of the caller's outputs; refused, naming `what`, when that
/// exceeds the memory available.
pub fn check_cut(
    what: &str,
    size: u32,
    spacing: f64,
    group_side: u32,
    coarse_cache: Option<u32>,
    output_bytes: u64,
) -> Result<u64> {
    let bricks = cut_bricks(size, spacing);
    check_sparse(
        what,
        bricks,
        size as f64 * spacing,
        group_side,
        coarse_cache,
        output_bytes,
    )
}

/// The bytes a sparse request (a cut, a surface's shell) of `bricks` requested 4^3-voxel bricks
/// spread over a surface `extent` voxels wide needs in groups of edge `group_side`, with
/// `output_bytes` of the caller's outputs; refused, naming `what`, when that exceeds the memory
/// available.
pub fn check_sparse(
    what: &str,
    bricks: u64,
    extent: f64,
    group_side: u32,
    coarse_cache: Option<u32>,
    output_bytes: u64,
) -> Result<u64> {
    let estimate = memory::sparse_working_bytes(bricks, extent, group_side, coarse_cache)
        .saturating_add(output_bytes);
    let available = crate::util::memory::available_memory();
    if estimate > available {
        return Err(Error::invalid(
            what,
            format!(
                "needs about {} of memory ({bricks} bricks of 4^3 voxels), {}",
                human_bytes(estimate),
                available_text(available)
            ),
        ));
    }
    Ok(estimate)
}
