//! solidsynth: solid texture synthesis from 2D exemplars, GPU-compute-first on wgpu/WGSL with a
//! CPU reference for every kernel.
//!
//! Start with [`lazy::analyze`] (exemplar analysis, the precomputation of "Lazy Solid Texture
//! Synthesis"), persisted with [`io::ssa`].

pub mod analysis;
pub mod backend;
pub mod contract;
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

pub use error::{Error, Result};
pub use lazy::Box3;
pub use solid::{Solid, SolidBuilder};
