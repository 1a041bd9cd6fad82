//! The driver settings a process sets for itself before its first GPU context: llvmpipe's
//! vector width on AVX-512 hosts, and what child processes inherit of it.

use super::GpuContext;

/// What a process asks of its GPU: compute kernels only, or also render pipelines (`lapped
/// render`), which llvmpipe cannot compile at 512-bit vectors (`RENDER_CRASHING_WIDTH`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriverUse {
    Compute,
    Rendering,
}

/// Set the driver environment this process's GPU work runs best with, once, before any GPU
/// context exists and before other threads may read the environment (it calls `set_var`):
/// on an AVX-512 host, llvmpipe (lavapipe) at 512-bit vectors for `Compute` and at 256 bits for
/// `Rendering` (render pipelines crash it at 512); a width the user set is kept; other drivers
/// ignore the variable. The first call decides. The library never calls it itself: the
/// `solidsynth` binary does, first thing in `main`; an application may, or may leave it.
pub fn prepare_driver_environment_for(work: DriverUse) {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| match work {
        DriverUse::Compute => prefer_full_width_cpu_vectors(),
        DriverUse::Rendering => render_safe_cpu_vectors(),
    });
}

/// llvmpipe at 256 bits on an AVX-512 host, unless the user set a width: not relying on Mesa's
/// default staying there ([`RENDER_CRASHING_WIDTH`]).
fn render_safe_cpu_vectors() {
    const VARIABLE: &str = "LP_NATIVE_VECTOR_WIDTH";
    if std::env::var_os(VARIABLE).is_none() && has_avx512() {
        std::env::set_var(VARIABLE, "256");
    }
}

/// llvmpipe's adapter name at the vector width whose render pipelines crash it: Mesa 22.3.6
/// (LLVM 15) and 26.2.6 (LLVM 22) both segfault in LLVM compiling `lapped_render`'s pipeline
/// at 512 bits on an AMD EPYC development machine, while every compute kernel here compiles and
/// runs there. A warm Mesa shader cache hides the crash: a pipeline compiled at 256 bits is read
/// back at 512 (the cache's key seems not to include the width), so CI runs with it disabled.
pub const RENDER_CRASHING_WIDTH: &str = "512 bits";

impl GpuContext {
    /// Whether this device is llvmpipe at `RENDER_CRASHING_WIDTH` (render pipelines refuse
    /// to run there rather than crash the process).
    pub fn render_pipelines_crash(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
            && self.info.name.contains("llvmpipe")
            && self.info.name.contains(RENDER_CRASHING_WIDTH)
    }
}

/// Mesa's llvmpipe (lavapipe, the Vulkan device of GPU-less machines) runs a shader 8 lanes wide
/// on an AVX-512 CPU unless `LP_NATIVE_VECTOR_WIDTH` says otherwise: Mesa chose 256 bits there for
/// CPUs that slow their clock on 512-bit instructions. At 512 bits every kernel here ran the same
/// bytes 1.3-1.4x faster on an AMD EPYC development machine (BENCHMARKS.md: 256^3, the bunny's
/// bake, warm cuts), so solidsynth asks for it on AVX-512 hosts; a value the user set is kept (256
/// restores Mesa's choice). Other drivers ignore the variable. Called once
/// ([`prepare_driver_environment_for`]), before the first wgpu instance exists.
fn prefer_full_width_cpu_vectors() {
    const VARIABLE: &str = "LP_NATIVE_VECTOR_WIDTH";
    if std::env::var_os(VARIABLE).is_some() || !has_avx512() {
        return;
    }
    std::env::set_var(VARIABLE, "512");
    WIDTH_SET_HERE.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// Whether this process set `LP_NATIVE_VECTOR_WIDTH` itself (`prefer_full_width_cpu_vectors`).
static WIDTH_SET_HERE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// A child process gets the user's driver environment, not what this process set for itself:
/// a `lapped render` started by `bench lapped --render` must choose its own width (a width it
/// inherits counts as the user's, and llvmpipe's render refuses 512 bits).
pub fn user_driver_environment(child: &mut std::process::Command) -> &mut std::process::Command {
    if WIDTH_SET_HERE.load(std::sync::atomic::Ordering::Relaxed) {
        child.env_remove("LP_NATIVE_VECTOR_WIDTH");
    }
    child
}

/// Whether the CPU has the AVX-512 subsets LLVM uses for 16-lane integer vectors.
fn has_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512vl")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
