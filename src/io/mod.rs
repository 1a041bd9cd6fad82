//! File formats and safe output.

pub mod atomic;
pub mod ssa;
