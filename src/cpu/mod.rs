//! CPU references of the WGSL kernels: one module per kernel, same name as its `wgsl/*.wgsl`.
//! Each mirrors its shader's loops and integer arithmetic, and is also the real, rayon-parallel
//! CPU backend.

pub mod bucket_accumulate;
pub mod colorize;
pub mod correct;
pub mod init;
// The render pipeline's reference is for its tests only: the CPU backend renders no models.
#[cfg(any(test, feature = "internals"))]
pub mod lapped_render;
pub mod project;
pub mod ptm_relight;
pub mod synth_common;
pub mod tricubic_eval;
pub mod upsample;
