//! File formats and safe output.

pub mod atomic;
pub mod flipbook;
pub mod input;
pub mod ktx2;
pub mod npy;
pub mod nrrd;
pub mod slab_order;
pub mod ssa;
pub mod tiff_stack;
pub mod vdb;
pub mod volume_file;
pub mod vti;
pub mod zarr;
