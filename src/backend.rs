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
    /// The GPU when an adapter exists, else the CPU (the choice is logged).
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
                Ok(ctx) => Ok(Compute::Gpu(Arc::new(ctx))),
                Err(e) => {
                    tracing::warn!("--backend auto: no usable GPU ({e}); running on the CPU");
                    Ok(Compute::Cpu)
                }
            },
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
