//! # solidsynth
//!
//! Solid textures from 2D exemplar images: colour for every point of 3D space, so an object
//! looks carved from a block of matter. The engine implements lazy solid texture synthesis
//! (Dong et al. 2008): an exemplar is analysed once; the solid is then a deterministic function
//! over all of Z^3, and any part of it (a box, a planar cut, a shell around a mesh) is
//! synthesized on demand, with the same voxels whichever part asked for them and whichever
//! backend (a GPU through wgpu/WGSL, or the CPU references) computed them.
//!
//! ```
//! use solidsynth::{Box3, CutSpec, Solid};
//!
//! // 1. Build: the built-in exemplar (or `.exemplar(image)`), analysed; the CPU backend.
//! let mut solid = Solid::builder().seed(42).cpu().build()?;
//! // 2. Any box of the infinite solid, at any coordinates.
//! let block = solid.region(Box3::new([-16, 0, 100], [16, 32, 104]))?;
//! assert_eq!(block.data.len(), 32 * 32 * 4 * solid.color_channels() as usize);
//! // 3. A planar cut at any angle, through the same solid.
//! let cut = solid.cut(&CutSpec {
//!     origin: [0.0, 16.0, 102.0],
//!     normal: [1.0, 1.0, 2.0],
//!     up: None,
//!     size: 64,
//!     spacing: 1.0,
//! })?;
//! assert_eq!((cut.width, cut.height), (64, 64));
//! # Ok::<(), solidsynth::Error>(())
//! ```
//!
//! Where to go next:
//! - [`Solid`] and [`SolidBuilder`]: the front door (exemplars, analysis cache, parameters,
//!   backend, progress, cancellation, memory estimates), with the command line's defaults.
//! - [`solid::surface`]: baking the solid onto a mesh ([`mesh`] loads OBJ, PLY and glTF).
//! - [`synth`]: what a synthesis request takes (boxes, cuts, parameters, options) and the
//!   warm [`CutSession`](synth::CutSession).
//! - [`device`]: the compute backends; [`GpuContext::from_device`] runs the engine on an
//!   application's own wgpu device.
//! - [`analysis`] and [`io::ssa`]: the analysis and its file; [`io::nrrd`] and the other
//!   [`io`] modules: volumes and images.
//! - The other three papers: [`gradient`] (gradient solid textures), [`ptm`] (relightable
//!   textures), [`lapped`] (lapped solid textures).
//!
//! Cargo features: `cli` (the `solidsynth` command line: argument parsing, progress bars and
//! logs) and `serve` (the local server), both on by default; `--no-default-features` builds the
//! engine alone. `internals` makes the engine's own layers (kernel contract, CPU and GPU kernels,
//! backends, the lazy synthesizer, utilities) public for the crate's tests and benchmarks; they
//! are not part of the API, carry no stability promise, and are `pub(crate)` without it.

/// Declares the engine's internal layers: `pub(crate)`, or public and hidden from the docs with
/// the `internals` feature (which the crate's own tests and benchmarks turn on, to compare each
/// kernel's CPU and GPU forms).
macro_rules! internal_modules {
    ($($name:ident),* $(,)?) => {
        $(
            #[cfg(feature = "internals")]
            #[doc(hidden)]
            pub mod $name;
            #[cfg(not(feature = "internals"))]
            pub(crate) mod $name;
        )*
    };
}

internal_modules!(backend, contract, cpu, gpu, lazy, util);

pub mod analysis;
/// The `solidsynth` command line (its doc comments are `--help` text, not rustdoc).
#[cfg(feature = "cli")]
#[doc(hidden)]
#[allow(rustdoc::broken_intra_doc_links)]
pub mod cli;
pub mod error;
pub mod exemplar;
pub mod gradient;
pub mod io;
pub mod lapped;
pub mod mesh;
pub mod metrics;
pub mod ptm;
#[cfg(feature = "serve")]
pub mod serve;
pub mod solid;
pub mod volume;

/// What a synthesis request takes: the box or cut, the solid's parameters and the engine's
/// options; the warm cut session and a request's statistics.
pub mod synth {
    pub use crate::backend::synthesis::KernelTimes;
    pub use crate::lazy::cut::{CutSession, CutSpec};
    pub use crate::lazy::{
        check_tileable_size, Box3, CandidateMode, ChannelSource, ChannelSources, ColorSource,
        PassSchedule, Slab, SynthOptions, SynthParams, SynthStats, Synthesizer, MAX_PASSES,
    };
    pub use crate::util::cancel::CancelToken;
}

/// The compute backends: the CPU references, or a GPU through wgpu (the crate's own device, or
/// an application's through [`GpuContext::from_device`]).
pub mod device {
    pub use crate::backend::{BackendChoice, Compute};
    pub use crate::gpu::context::{
        list_adapters, prepare_driver_environment_for, required_limits, user_driver_environment,
        DriverUse,
    };
    pub use crate::gpu::{GpuContext, GpuOptions};
}

pub use device::{BackendChoice, Compute, GpuContext, GpuOptions};
pub use error::{Error, Result};
pub use exemplar::Image;
pub use solid::{Solid, SolidBuilder};
pub use synth::{Box3, CancelToken, CutSpec, SynthOptions, SynthParams};
pub use volume::Volume;
