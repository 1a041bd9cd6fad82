//! GPU-vs-CPU tests of every WGSL kernel, one file per kernel named like it (`kernel_files`
//! enforces that), plus whole syntheses (`synth`): one test binary, run on whatever Vulkan adapter wgpu
//! finds (Mesa lavapipe in CI). With `CI` set, a missing adapter fails the run: a skipped GPU
//! test must never look like a passing one.

mod bucket_accumulate;
mod buffers;
mod colorize;
mod compare;
mod correct;
mod init;
mod kernel_files;
mod lapped_render;
mod project;
mod ptm_relight;
mod shaders;
mod synth;
mod synth_inputs;
mod tricubic_eval;
mod upsample;

use solidsynth::gpu::{GpuContext, GpuOptions};
use std::sync::OnceLock;

/// Every test of this binary holds this lock while it runs: the GPU tests run one at a time.
/// In parallel they failed intermittently inside wgpu 30 ("Mismatched pop_error_scope call: error
/// scopes must be popped in reverse order", raised in `GpuContext::checked` on a test's own
/// thread) although each thread pushes and pops its scopes in order; the cause is not found.
pub fn serial() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The shared context, or None (locally, without an adapter: the test prints SKIPPED).
pub fn gpu() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| open(GpuOptions::from_env())).as_ref()
}

/// Open a context with `opts`, failing hard in CI when there is no adapter.
pub fn open(opts: GpuOptions) -> Option<GpuContext> {
    match GpuContext::new(&opts) {
        Ok(ctx) => {
            eprintln!("kernels-tests adapter: {}", ctx.describe());
            Some(ctx)
        }
        Err(e) if std::env::var_os("CI").is_some() => {
            panic!("CI is set but no GPU adapter is usable: {e}")
        }
        Err(e) => {
            eprintln!("SKIPPED (no GPU adapter, CI unset): {e}");
            None
        }
    }
}
