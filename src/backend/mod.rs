//! Choosing where kernels run (`--backend gpu|cpu|auto`), and the one door through which the
//! domains call each kernel: a method of [`Compute`] per kernel, or, for the four synthesis
//! kernels whose level data stays resident between calls, [`synthesis::Executor`]. Nothing above
//! this layer names `cpu::` or `gpu::` kernels.

pub mod synthesis;

use crate::contract::buckets::Buckets;
use crate::contract::lapped::{Camera, RenderScene};
use crate::contract::pca::PcaBasis;
use crate::contract::ptm::{Lighting, Ptm};
use crate::contract::tricubic::{GradientSolid, Query};
use crate::error::{Error, Result};
use crate::exemplar::{Border, Image};
use crate::gpu::{GpuContext, GpuOptions};
use std::sync::Arc;

/// The CPU backend's streaming form of `bucket_accumulate` (see `cpu::bucket_accumulate`).
pub mod buckets {
    pub use crate::contract::buckets::Buckets;
    pub use crate::cpu::bucket_accumulate::{
        dominant, PackedSums,
    };
}

/// The user's choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
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

/// `auto`, `cpu` or `gpu`, as `--backend` spells them (for callers without clap, e.g. Python).
impl std::str::FromStr for BackendChoice {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        match text {
            "auto" => Ok(BackendChoice::Auto),
            "cpu" => Ok(BackendChoice::Cpu),
            "gpu" => Ok(BackendChoice::Gpu),
            _ => Err("expected auto, cpu or gpu".into()),
        }
    }
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

    /// Largest storage binding of this backend's kernels, bytes (the CPU's: no binding limit
    /// beyond what a `Vec` indexes with u32 words).
    pub fn max_binding_bytes(&self) -> u64 {
        match self {
            Compute::Cpu => 4 * u32::MAX as u64,
            Compute::Gpu(g) => g.max_binding_bytes(),
        }
    }

    /// Kernel `tricubic_eval`: `solid.channels` values per point of `query`, in query order.
    pub fn tricubic_eval(&self, solid: &GradientSolid, query: &Query) -> Result<Vec<f32>> {
        solid.check()?;
        match self {
            Compute::Cpu => Ok(crate::cpu::tricubic_eval::tricubic_eval(solid, query)),
            Compute::Gpu(g) => crate::gpu::tricubic_eval::tricubic_eval(g, solid, query),
        }
    }

    /// Kernel `tricubic_eval` in its 8-bit mode where the GPU has it (at most four channels),
    /// else its values quantized on the host: the same bytes either way.
    pub fn tricubic_eval_u8(&self, solid: &GradientSolid, query: &Query) -> Result<Vec<u8>> {
        use crate::cpu::tricubic_eval::{quantize, tricubic_eval_u8};
        solid.check()?;
        match self {
            Compute::Cpu => Ok(tricubic_eval_u8(solid, query)),
            Compute::Gpu(g) if solid.channels <= 4 => {
                crate::gpu::tricubic_eval::tricubic_eval_u8(g, solid, query)
            }
            Compute::Gpu(g) => Ok(crate::gpu::tricubic_eval::tricubic_eval(g, solid, query)?
                .into_iter()
                .map(quantize)
                .collect()),
        }
    }

    /// Kernel `ptm_relight`: r, g, b per pixel (unit intensity, unclamped) under `light`.
    pub fn ptm_relight(&self, ptm: &Ptm, light: &Lighting) -> Result<Vec<f32>> {
        // (The kernels index texels by the PTM's sizes.)
        ptm.check("PTM")?;
        match self {
            Compute::Cpu => Ok(crate::cpu::ptm_relight::ptm_relight(ptm, light)),
            Compute::Gpu(g) => crate::gpu::ptm_relight::ptm_relight(g, ptm, light),
        }
    }

    /// A PTM held by the backend for relighting under many lights (on the GPU its texels are
    /// uploaded once).
    pub fn resident_ptm<'a>(&'a self, ptm: &'a Ptm) -> ResidentPtm<'a> {
        match self {
            Compute::Cpu => ResidentPtm::Cpu(ptm),
            Compute::Gpu(g) => ResidentPtm::Gpu(g, crate::gpu::ptm_relight::GpuPtm::upload(g, ptm)),
        }
    }

    /// Kernel `bucket_accumulate` over the samples `parts` hold end to end.
    pub fn bucket_accumulate_parts(
        &self,
        parts: &[&[u32]],
        voxels: usize,
        clusters: u32,
        channels: u32,
    ) -> Result<Buckets> {
        match self {
            Compute::Cpu => Ok(crate::cpu::bucket_accumulate::bucket_accumulate(
                &parts.concat(),
                voxels,
                clusters,
                channels,
            )),
            Compute::Gpu(g) => crate::gpu::bucket_accumulate::bucket_accumulate_parts(
                g, parts, voxels, clusters, channels,
            ),
        }
    }

    /// The render pipeline `lapped_render`: `scene` seen from `camera` in a size x size RGBA
    /// image. It has no CPU backend (its CPU reference is a per-pixel ray cast for tests).
    pub fn lapped_render(
        &self,
        scene: &RenderScene,
        camera: &Camera,
        size: u32,
    ) -> Result<image::RgbaImage> {
        match self {
            Compute::Cpu => Err(Error::invalid(
                "--backend cpu",
                "rendering needs a GPU adapter (lavapipe works)",
            )),
            Compute::Gpu(g) => crate::gpu::lapped_render::render(g, scene, camera, size),
        }
    }
}

/// The CPU backend's `tricubic_eval`, for host-side work that needs no device (a region's
/// signed distances, a detail fit).
pub fn host_tricubic_eval(solid: &GradientSolid, query: &Query) -> Vec<f32> {
    crate::cpu::tricubic_eval::tricubic_eval(solid, query)
}

/// A PTM on a backend, ready to relight ([`Compute::resident_ptm`]).
pub enum ResidentPtm<'a> {
    Cpu(&'a Ptm),
    Gpu(&'a GpuContext, crate::gpu::ptm_relight::GpuPtm),
}

impl ResidentPtm<'_> {
    /// Kernel `ptm_relight` under `light`.
    pub fn relight(&self, light: &Lighting) -> Result<Vec<f32>> {
        match self {
            ResidentPtm::Cpu(ptm) => Ok(crate::cpu::ptm_relight::ptm_relight(ptm, light)),
            ResidentPtm::Gpu(g, resident) => resident.relight(g, light),
        }
    }
}
