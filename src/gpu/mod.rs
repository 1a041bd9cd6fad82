//! GPU runtime: the context (adapter, device, bounded waits, chunking) and one dispatch module per
//! kernel, named like its `wgsl/*.wgsl`.

pub mod bucket_accumulate;
pub mod candidate_tables;
pub mod context;
pub mod lapped_render;
pub mod project;
mod projection_weights;
pub mod ptm_relight;
pub mod shaders;
pub mod synth;
pub mod tricubic_eval;

pub use context::{GpuContext, GpuOptions};
