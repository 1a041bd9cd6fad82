//! Small shared helpers.

pub mod hash;
pub mod memory;
