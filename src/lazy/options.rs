//! How a synthesizer runs: tuning given at construction that never changes a voxel (the tests
//! compare every setting's bytes), with the library's defaults.

use crate::error::{Error, Result};
use crate::contract::bricks::BRICK;
use crate::util::cancel::CancelToken;

/// How a `super::Synthesizer` runs. `Default` is the library's choice for the backend, the
/// same the command-line tool and the server use.
#[derive(Clone, Debug, Default)]
pub struct SynthOptions {
    /// The largest group edge in voxels ([`MAX_GROUP_SIDES`]), rounded down to whole bricks
    /// (`--max-group`): groups
    /// bound the working memory. None: the library's default, groups of at most
    /// `super::memory::HOST_MEMORY_GROUP` for boxes, tileable solids and brick sets (surfaces)
    /// where the backend's memory is the host's, else as large as the backend's buffers allow;
    /// sampled voxels (cuts) in as few groups as the backend allows.
    pub max_group: Option<u32>,
    /// When a request takes several groups: whether the levels above the finest are
    /// synthesized once for all of them (level by level, each in groups of its own if it too is
    /// large) and their triples held on the host until every group has read its parents,
    /// instead of once per group with the group's padding. Shared levels save the coarse
    /// levels' repeated padding (a quarter of the time of a 256^3 box in eight groups on
    /// lavapipe) for about 0.9 bytes of host memory per finest-level voxel (1.7 for exemplars
    /// over 512 pixels). None: shared on the CPU backend and on GPUs that share the host's
    /// memory (a 256^3 box in 64-voxel groups on the CPU backend of a 2-core Xeon: 20.7 s with
    /// each group's own coarse levels, 15.3 s shared, for 6 MiB more); not on a GPU with its own
    /// memory, where reading the shared levels back and building each group's parents on the
    /// host cost more than the recomputed padding (H200: 512^3 in eight groups 1.71-1.74 s
    /// shared, 1.13-1.22 s not; the bunny at 1024 in 16 groups 2.0 against 1.04-1.11 s).
    pub shared_coarse_levels: Option<bool>,
    /// A warm session: the GPU keeps its state and colour buffers from one request for the
    /// next ones of the same sizes, and neither backend hands free heap back between groups.
    pub keep_buffers: bool,
    /// Time every kernel (waiting for the device after each, so totals grow slightly); read
    /// with `super::Synthesizer::kernel_times`.
    pub profile: bool,
    /// Checked before every group and every correction pass: once cancelled, a request stops
    /// there with [`Error::Cancelled`] and delivers nothing more.
    pub cancel: Option<CancelToken>,
    /// Tests: hold each level's state of a group within this many bytes (or the backend's
    /// buffer limit, when lower), which is what sizes the groups.
    #[doc(hidden)]
    pub state_limit: Option<u64>,
    /// Tests: whether a request of several groups reads each group's colours back while the
    /// next one runs (GPU only). None: on a GPU whose memory is its own.
    #[doc(hidden)]
    pub overlapped_reads: Option<bool>,
}

impl SynthOptions {
    /// Refuse settings no synthesis can run with, named as the command line names them.
    pub fn validate(&self) -> Result<()> {
        if let Some(side) = self.max_group {
            // Groups are whole 4^3-voxel bricks: another side would be rounded down unseen.
            if !MAX_GROUP_SIDES.contains(&side) || !side.is_multiple_of(BRICK as u32) {
                return Err(Error::invalid(
                    format!("--max-group {side}"),
                    format!(
                        "must be a multiple of {BRICK} (whole bricks) in {}..={}",
                        MAX_GROUP_SIDES.start(),
                        MAX_GROUP_SIDES.end()
                    ),
                ));
            }
        }
        if self.state_limit == Some(0) {
            return Err(Error::invalid("state limit", "must be at least one byte"));
        }
        Ok(())
    }
}

/// The group edges `max_group` may take (`--max-group`), in finest-level voxels.
pub const MAX_GROUP_SIDES: std::ops::RangeInclusive<u32> = 4..=512;

/// What a request asks for, for the defaults that depend on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum RequestKind {
    /// A box or a tileable solid.
    Volume,
    /// Whole bricks (a surface's shell).
    Bricks,
    /// Sampled voxels (a cut).
    Voxels,
}
