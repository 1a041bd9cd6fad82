//! File formats and safe output.

pub mod atomic;
pub mod flipbook;
pub mod nrrd;
pub mod ssa;
pub mod vti;
