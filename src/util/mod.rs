//! Small shared helpers.

pub mod cancel;
pub mod hash;
pub mod memory;
