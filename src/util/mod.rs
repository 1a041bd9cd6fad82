//! Small shared helpers.

pub mod cancel;
pub mod disk;
pub mod hash;
pub mod memory;
