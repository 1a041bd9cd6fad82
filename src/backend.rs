//! Choosing where kernels run: `--backend gpu|cpu|auto`.

use crate::analysis::pca::PcaBasis;
use crate::error::Result;
use crate::exemplar::{Border, Image};
use crate::gpu::{GpuContext, GpuOptions};
use std::sync::Arc;

/// The user's choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendChoice {
    /// A GPU adapter (any Vulkan device, lavapipe included); an error when there is none.
    Gpu,
    /// The rayon-parallel CPU references.
    Cpu,
    /// A hardware GPU when one exists, else the CPU backend (the choice is logged). A software
    /// Vulkan device such as lavapipe is not chosen here: it runs on the same CPU cores and is
    /// slower than the native CPU backend; ask for it with `--backend gpu`.
    Auto,
}

/// An opened backend.
#[derive(Clone)]
pub enum Compute {
    Cpu,
    Gpu(Arc<GpuContext>),
}

impl Compute {
    pub fn open(choice: BackendChoice, opts: &GpuOptions) -> Result<Compute> {
        match choice {
            BackendChoice::Cpu => Ok(Compute::Cpu),
            BackendChoice::Gpu => Ok(Compute::Gpu(Arc::new(GpuContext::new(opts)?))),
            BackendChoice::Auto => match GpuContext::new(opts) {
                Ok(ctx) if ctx.info.device_type != wgpu::DeviceType::Cpu => {
                    Ok(Compute::Gpu(Arc::new(ctx)))
                }
                Ok(ctx) => {
                    tracing::info!(
                        "--backend auto: only a software adapter ({}); the CPU backend is faster, using it",
                        ctx.info.name
                    );
                    Ok(Compute::Cpu)
                }
                Err(e) => {
                    tracing::info!("--backend auto: no GPU adapter ({e}); using the CPU backend");
                    Ok(Compute::Cpu)
                }
            },
        }
    }

    /// Whether the kernels' memory is the host's: the CPU backend, or a software or integrated
    /// GPU adapter (lavapipe, a laptop's GPU), where a request's working memory competes with
    /// everything else the machine holds.
    pub fn memory_is_hosts(&self) -> bool {
        match self {
            Compute::Cpu => true,
            Compute::Gpu(g) => matches!(
                g.info.device_type,
                wgpu::DeviceType::Cpu | wgpu::DeviceType::IntegratedGpu
            ),
        }
    }

    pub fn describe(&self) -> String {
        match self {
            Compute::Cpu => format!("cpu ({} threads)", rayon::current_num_threads()),
            Compute::Gpu(g) => format!("gpu {}", g.describe()),
        }
    }

    /// Kernel `project` on this backend.
    pub fn project(&self, img: &Image, border: Border, pca: &PcaBasis) -> Result<Vec<u32>> {
        match self {
            Compute::Cpu => Ok(crate::cpu::project::project(img, border, pca)),
            Compute::Gpu(g) => crate::gpu::project::project(g, img, border, pca),
        }
    }
}
