//! GPU runtime: the context (adapter, device, bounded waits, chunking), one dispatch module per
//! kernel, named like its `wgsl/*.wgsl`, and the synthesis kernels' resident state (`synth`).

pub mod bucket_accumulate;
pub mod candidate_tables;
pub mod colorize;
pub mod context;
pub mod correct;
pub mod init;
pub mod lapped_render;
pub mod project;
mod projection_weights;
pub mod ptm_relight;
pub mod shaders;
pub mod synth;
pub mod tricubic_eval;
pub mod upsample;

pub use context::{GpuContext, GpuOptions};
