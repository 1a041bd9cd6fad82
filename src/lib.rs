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
//! use solidsynth::{lazy::cut::CutSpec, Box3, Solid};
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
//! - [`solid::surface`]: baking the solid onto a mesh ([`mesh`] loads OBJ and PLY).
//! - [`gpu::GpuContext::from_device`]: run on an application's own wgpu device.
//! - [`lazy`]: the engine underneath (requests, options, cuts); [`analysis`] and [`io::ssa`]:
//!   the analysis and its file; [`io::nrrd`]: volumes.
//! - The other three papers: [`gradient`] (gradient solid textures), [`ptm`] (relightable
//!   textures), [`lapped`] (lapped solid textures).
//!
//! Cargo features: `cli` (the `solidsynth` binary's argument parsing, progress bars and logs)
//! and `serve` (the local server), both on by default; `--no-default-features` builds the
//! engine alone.

pub mod analysis;
pub mod backend;
#[doc(hidden)]
pub mod contract;
#[doc(hidden)]
pub mod cpu;
pub mod error;
pub mod exemplar;
pub mod gpu;
pub mod gradient;
pub mod io;
pub mod lapped;
pub mod lazy;
pub mod mesh;
pub mod metrics;
pub mod ptm;
#[cfg(feature = "serve")]
pub mod serve;
pub mod solid;
pub mod util;
pub mod volume;

pub use backend::{BackendChoice, Compute};
pub use error::{Error, Result};
pub use exemplar::Image;
pub use lazy::cut::CutSpec;
pub use lazy::{Box3, SynthOptions, SynthParams};
pub use solid::{Solid, SolidBuilder};
pub use util::cancel::CancelToken;
pub use volume::Volume;
