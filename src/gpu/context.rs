//! `GpuContext`: one wgpu device chosen by name filter, with bounded waits and helpers to split
//! work that exceeds the adapter's storage-binding limit.
//!
//! Length: about 800 lines because the device, its limits, buffers, bounded waits, reads and
//! pipeline cache are one object's (`GpuContext`) methods.

use crate::error::{Error, Result};
use std::collections::HashMap;
use std::ops::Range;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use wgpu::util::DeviceExt;

/// Environment variable naming a substring of the adapter to use (like `--adapter`).
pub const ADAPTER_ENV: &str = "SOLIDSYNTH_ADAPTER";
/// Environment variable overriding the bound on any single wait for the GPU, in seconds.
pub const TIMEOUT_ENV: &str = "SOLIDSYNTH_GPU_TIMEOUT_S";
/// Environment variable choosing the layout of 16-bit projection weights (`bytes` or `halves`,
/// the default), for timing the two on a device without rebuilding ([`GpuOptions::byte_weights`]).
pub const WEIGHT_LAYOUT_ENV: &str = "SOLIDSYNTH_WEIGHT_LAYOUT";
/// Threads per workgroup of the 1D kernels.
pub const WORKGROUP_SIZE: u32 = 64;

/// How to pick and drive the adapter.
#[derive(Clone, Debug)]
pub struct GpuOptions {
    /// Case-insensitive substring the adapter name must contain.
    pub adapter_filter: Option<String>,
    /// Upper bound on any single wait for the device.
    pub timeout: Duration,
    /// Use a smaller storage-binding limit than the adapter's (tests exercise chunking with it).
    pub max_binding_bytes: Option<u64>,
    /// Lay 16-bit projection weights out as bytes for packed dot products instead of as halves
    /// (`SOLIDSYNTH_WEIGHT_LAYOUT=bytes`; `gpu::synth::WeightLayout`).
    pub byte_weights: bool,
}

impl Default for GpuOptions {
    fn default() -> Self {
        GpuOptions {
            adapter_filter: None,
            timeout: Duration::from_secs(120),
            max_binding_bytes: None,
            byte_weights: false,
        }
    }
}

impl GpuOptions {
    /// Defaults, with the adapter filter and timeout taken from the environment when set.
    pub fn from_env() -> Self {
        let mut o = GpuOptions::default();
        o.adapter_filter = std::env::var(ADAPTER_ENV).ok().filter(|s| !s.is_empty());
        if let Some(s) = std::env::var(TIMEOUT_ENV)
            .ok()
            .and_then(|s| s.parse::<f64>().ok())
        {
            if s > 0.0 {
                o.timeout = Duration::from_secs_f64(s);
            }
        }
        o.byte_weights = match std::env::var(WEIGHT_LAYOUT_ENV).as_deref() {
            Ok("bytes") => true,
            Ok("halves") | Err(_) => false,
            Ok(other) => {
                tracing::warn!("{WEIGHT_LAYOUT_ENV}={other} ignored: not bytes or halves");
                false
            }
        };
        o
    }
}

/// A device and queue with the helpers every dispatch module uses.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    timeout: Duration,
    max_binding_bytes: u64,
    /// [`GpuOptions::byte_weights`].
    pub byte_weights: bool,
    pipelines: Mutex<HashMap<String, Arc<wgpu::ComputePipeline>>>,
    /// The last read-back staging buffer up to [`REUSED_READBACK_BYTES`], kept for the next
    /// read (a warm cut session reads one per cut: no allocation on the request path).
    readback: Mutex<Option<wgpu::Buffer>>,
    /// GPU errors raised outside an error scope, reported at the next wait instead of panicking.
    uncaptured: Arc<Mutex<Option<String>>>,
}

/// A Vulkan instance. The driver settings this crate prefers (llvmpipe's vector width) are the
/// binary's to set, before its first thread ([`prepare_driver_environment_for`]): a library sets
/// no process-wide state.
fn new_instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::VULKAN;
    wgpu::Instance::new(desc)
}

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

/// Read-back staging buffers up to this size are kept for the next read; larger reads (whole
/// volumes) allocate their own, so memory is not held after them.
const REUSED_READBACK_BYTES: u64 = 16 << 20;

/// Kernel `name`'s WGSL: the embedded source, or, for kernel development (timing variants on a
/// device without rebuilding), `$SOLIDSYNTH_SHADER_DIR/NAME.wgsl` when that variable is set and
/// the file exists. An override must be the complete source (prelude included); it is logged as
/// a warning, since its results are only as exact as the file.
fn shader_source(name: &'static str) -> Result<std::borrow::Cow<'static, str>> {
    if let Some(dir) = std::env::var_os("SOLIDSYNTH_SHADER_DIR") {
        let path = std::path::Path::new(&dir).join(format!("{name}.wgsl"));
        if path.exists() {
            tracing::warn!(
                "kernel {name} from {} (SOLIDSYNTH_SHADER_DIR)",
                path.display()
            );
            return std::fs::read_to_string(&path)
                .map(std::borrow::Cow::Owned)
                .map_err(|e| Error::io(&path, e));
        }
    }
    Ok(std::borrow::Cow::Borrowed(super::shaders::source(name)))
}

/// Every adapter wgpu can see (name, type, backend), for `--list-adapters` and error messages.
pub fn list_adapters() -> Vec<wgpu::AdapterInfo> {
    let instance = new_instance();
    pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN))
        .iter()
        .map(|a| a.get_info())
        .collect()
}

fn type_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// How wgpu sub-allocates device memory. On a CPU adapter (lavapipe, whose device memory is the
/// process's shared memory) small blocks: with wgpu's default, host-visible blocks of 64-128 MiB
/// (every lavapipe memory type is host-visible), a block's pages are touched as buffers come
/// and go and stay resident until the device closes; with these hints the blocks are 4 MiB
/// (gpu-allocator halves the range for host-visible memory), and a buffer larger than one gets
/// its own, returned to the system when it is dropped (the coarse levels' candidate tables
/// after the coarse cache, a finished group's states). Integrated GPUs keep the default: not
/// measured.
fn memory_hints(device_type: wgpu::DeviceType) -> wgpu::MemoryHints {
    match device_type {
        wgpu::DeviceType::Cpu => wgpu::MemoryHints::Manual {
            suballocated_device_memory_block_size: (4 << 20)..(8 << 20),
        },
        _ => wgpu::MemoryHints::Performance,
    }
}

impl GpuContext {
    /// Pick the best adapter matching the filter (discrete > integrated > virtual > CPU, e.g.
    /// lavapipe) and open a device with the adapter's own limits.
    pub fn new(opts: &GpuOptions) -> Result<Self> {
        let instance = new_instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
        let names: Vec<String> = adapters
            .iter()
            .map(|a| format!("{} ({:?})", a.get_info().name, a.get_info().device_type))
            .collect();
        let filter = opts.adapter_filter.as_ref().map(|f| f.to_lowercase());
        // An adapter named exactly as the filter wins over those whose names merely contain it
        // ("RTX 4070" is not the "RTX 4070 Ti"), then hardware over software.
        let chosen = adapters
            .into_iter()
            .filter(|a| match &filter {
                Some(f) => a.get_info().name.to_lowercase().contains(f.as_str()),
                None => true,
            })
            .min_by_key(|a| {
                let info = a.get_info();
                let exact = filter.as_deref() == Some(info.name.to_lowercase().as_str());
                (!exact, type_rank(info.device_type))
            });
        let adapter = chosen.ok_or_else(|| {
            if names.is_empty() {
                Error::Gpu(
                    "no Vulkan adapter found; install a Vulkan driver (e.g. Debian's \
                     mesa-vulkan-drivers for the lavapipe CPU device) or use --backend cpu"
                        .into(),
                )
            } else {
                Error::Gpu(format!(
                    "no adapter matches '{}' (from --adapter or {ADAPTER_ENV}); available: {}",
                    opts.adapter_filter.as_deref().unwrap_or(""),
                    names.join(", ")
                ))
            }
        })?;
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("solidsynth"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            memory_hints: memory_hints(info.device_type),
            ..Default::default()
        }))
        .map_err(|e| Error::Gpu(format!("cannot open device on {}: {e}", info.name)))?;
        tracing::info!(
            adapter = %info.name,
            device_type = ?info.device_type,
            driver = %info.driver,
            max_storage_binding = limits.max_storage_buffer_binding_size,
            "GPU adapter"
        );
        Ok(Self::with_device(device, queue, info, limits, opts))
    }

    /// A context over an application's own device and queue (a game engine's, a viewer's):
    /// the kernels run there, sharing its memory and queue. `info` is its adapter's. Refused,
    /// naming the limit, when the device's limits are below what the kernels need
    /// ([`required_limits`]); nothing process-wide is changed.
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: wgpu::AdapterInfo,
        opts: &GpuOptions,
    ) -> Result<Self> {
        let limits = device.limits();
        if let Some(problem) = missing_limit(&limits) {
            return Err(Error::invalid("device", problem));
        }
        tracing::info!(adapter = %info.name, "GPU device given by the application");
        Ok(Self::with_device(device, queue, info, limits, opts))
    }

    fn with_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: wgpu::AdapterInfo,
        limits: wgpu::Limits,
        opts: &GpuOptions,
    ) -> Self {
        // The largest binding: the device's, or less when the options ask for it.
        let device_max = limits.max_storage_buffer_binding_size as u64;
        let max_binding_bytes = opts
            .max_binding_bytes
            .map_or(device_max, |m| m.min(device_max));
        let uncaptured = Arc::new(Mutex::new(None));
        let sink = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut slot = sink.lock().unwrap();
            if slot.is_none() {
                *slot = Some(e.to_string());
            }
        }));
        GpuContext {
            uncaptured,
            device,
            queue,
            info,
            limits,
            timeout: opts.timeout,
            max_binding_bytes,
            byte_weights: opts.byte_weights,
            pipelines: Mutex::new(HashMap::new()),
            readback: Mutex::new(None),
        }
    }

    /// A one-line description of the adapter, for logs and benchmark tables.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            self.info.name,
            self.info.device_type,
            self.info.backend,
            self.info.driver,
            self.info.driver_info
        )
    }

    /// The largest buffer one storage binding may cover.
    pub fn max_binding_bytes(&self) -> u64 {
        self.max_binding_bytes
    }

    /// Forget the cached pipeline of kernel `name` with `constants` (as given to
    /// [`Self::pipeline_with`]): it is destroyed once the work that uses it is done, and built
    /// again if it is asked for again.
    pub fn release_pipeline(&self, name: &'static str, constants: &[(&str, f64)]) {
        self.pipelines
            .lock()
            .unwrap()
            .remove(&format!("{name}{constants:?}"));
    }

    /// The compute pipeline of kernel `name` (entry point `main`), built once and cached.
    pub fn pipeline(&self, name: &'static str) -> Result<Arc<wgpu::ComputePipeline>> {
        self.pipeline_with(name, &[])
    }

    /// Build the pipelines of `kernels` (name, constants) that are not built yet, each on a
    /// thread of its own (up to the machine's cores at once): a shader compile is single-threaded
    /// work of the driver (lavapipe's LLVM: ~0.2 s for `correct`), which a synthesis otherwise
    /// waits for one variant after the other at its first dispatch of each level. (Error scopes
    /// are per thread in wgpu, so each build checks its own.)
    pub fn prebuild_pipelines(
        &self,
        kernels: &[(&'static str, Vec<(&'static str, f64)>)],
    ) -> Result<()> {
        let mut wanted: Vec<&(&'static str, Vec<(&'static str, f64)>)> = Vec::new();
        {
            let built = self.pipelines.lock().unwrap();
            for k in kernels {
                if !built.contains_key(&format!("{}{:?}", k.0, k.1)) && !wanted.contains(&k) {
                    wanted.push(k);
                }
            }
        }
        // Workers take the next unbuilt kernel until none is left.
        let next = std::sync::atomic::AtomicUsize::new(0);
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads.min(wanted.len()))
                .map(|_| {
                    scope.spawn(|| loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some((name, constants)) = wanted.get(i) else {
                            return Ok(());
                        };
                        self.pipeline_with(name, constants)?;
                    })
                })
                .collect();
            workers
                .into_iter()
                .try_for_each(|worker| match worker.join() {
                    Ok(built) => built,
                    Err(panic) => std::panic::resume_unwind(panic),
                })
        })?;
        Ok(())
    }

    /// The pipeline of kernel `name` with its WGSL `override` constants set, built once per set
    /// of values and cached (constant loop bounds let the driver unroll the kernel's loops).
    pub fn pipeline_with(
        &self,
        name: &'static str,
        constants: &[(&str, f64)],
    ) -> Result<Arc<wgpu::ComputePipeline>> {
        let key = format!("{name}{constants:?}");
        if let Some(p) = self.pipelines.lock().unwrap().get(&key) {
            return Ok(p.clone());
        }
        let timer = std::time::Instant::now();
        let source = shader_source(name)?;
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(source),
            });
        let pipeline = self
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            });
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu(format!("kernel {name}: {err}")));
        }
        let pipeline = Arc::new(pipeline);
        // A software driver's shader compiler (lavapipe's LLVM) frees tens of MB as it
        // finishes, which glibc would otherwise keep for the rest of the run.
        drop(module);
        crate::util::memory::return_free_heap();
        tracing::debug!(
            "kernel {name}: pipeline built in {:.1} ms",
            timer.elapsed().as_secs_f64() * 1e3
        );
        self.pipelines.lock().unwrap().insert(key, pipeline.clone());
        Ok(pipeline)
    }

    /// A read-only storage buffer holding `bytes` (padded to 4 bytes, at least 4).
    pub fn storage_buffer(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        // (Copied to pad only when needed: most uploads are whole words, some of them large.)
        let padded;
        let contents = if bytes.len() % 4 == 0 && !bytes.is_empty() {
            bytes
        } else {
            let mut p = bytes.to_vec();
            p.resize(bytes.len().next_multiple_of(4).max(4), 0);
            padded = p;
            &padded
        };
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// [`Self::storage_buffer`] for large contents kept for long (a synthesis' level data and
    /// candidate tables): uploaded in pieces of `UPLOAD_PIECE_BYTES`, each waited for. wgpu
    /// stages an upload in memory of its own until its copy has run, so an upload made whole
    /// holds its bytes twice, and on lavapipe, whose device memory is host memory, the staging
    /// pages stay with the process: the built-in exemplar's 31 MiB of level data and tables
    /// took 61 MiB of device memory; in pieces, 31 plus one piece.
    pub fn storage_buffer_in_pieces(&self, label: &str, bytes: &[u8]) -> Result<wgpu::Buffer> {
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.len().next_multiple_of(4).max(4) as u64,
            // (COPY_SRC: the kernels-tests read it back.)
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        self.checked(label, || {
            for (i, piece) in bytes.chunks(UPLOAD_PIECE_BYTES).enumerate() {
                let offset = (i * UPLOAD_PIECE_BYTES) as u64;
                if piece.len() % 4 == 0 {
                    self.queue.write_buffer(&buffer, offset, piece);
                } else {
                    let mut padded = piece.to_vec();
                    padded.resize(piece.len().next_multiple_of(4), 0);
                    self.queue.write_buffer(&buffer, offset, &padded);
                }
                let index = self.queue.submit(None);
                self.wait(Some(index))?;
            }
            Ok(())
        })?;
        Ok(buffer)
    }

    /// A storage buffer holding `parts` end to end (at least one word), copied straight into
    /// the mapped buffer: no joined copy on the host.
    pub fn storage_buffer_parts(&self, label: &str, parts: &[&[u32]]) -> Result<wgpu::Buffer> {
        let words: usize = parts.iter().map(|p| p.len()).sum();
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (words.max(1) * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: true,
        });
        {
            let mut mapped = buffer
                .slice(..)
                .get_mapped_range_mut()
                .map_err(|e| Error::Gpu(format!("{label}: buffer mapping failed: {e}")))?;
            let mut at = 0;
            for part in parts {
                let bytes: &[u8] = bytemuck::cast_slice(part);
                mapped.slice(at..at + bytes.len()).copy_from_slice(bytes);
                at += bytes.len();
            }
        }
        buffer.unmap();
        Ok(buffer)
    }

    /// A uniform buffer holding `value`.
    pub fn uniform_buffer<T: bytemuck::Pod>(&self, label: &str, value: &T) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::bytes_of(value),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// A read-write storage buffer of `words` u32 that the kernels fill entirely before anything
    /// reads it (a synthesis state). Not filled on the host: wgpu zero-initializes it on the
    /// device, where an [`Self::output_buffer`] would first fill and upload `words` sentinels
    /// (at 256^3 about a gigabyte of states per synthesis).
    pub fn device_buffer(&self, label: &str, words: usize) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (words.max(1) * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// A read-write storage buffer of `words` u32, pre-filled with `sentinel` so a value the
    /// kernel never wrote is distinguishable from one it wrote.
    /// A zero sentinel costs nothing: wgpu zeroes new buffers on the device.
    pub fn output_buffer(&self, label: &str, words: usize, sentinel: u32) -> wgpu::Buffer {
        if sentinel == 0 {
            return self.device_buffer(label, words);
        }
        let fill = vec![sentinel; words.max(1)];
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(&fill),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// Bind `buffers` to bindings 0, 1, ... of `pipeline`'s group 0, dispatch `groups`
    /// workgroups (x, y) and wait (bounded).
    pub fn dispatch_and_wait(
        &self,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
        groups: (u32, u32),
    ) -> Result<()> {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(groups.0, groups.1, 1);
        }
        self.submit_and_wait(encoder)
    }

    /// Submit `encoder` and wait for it, bounded by the timeout.
    pub fn submit_and_wait(&self, encoder: wgpu::CommandEncoder) -> Result<()> {
        let index = self.queue.submit(Some(encoder.finish()));
        self.wait(Some(index))
    }

    fn wait(&self, index: Option<wgpu::SubmissionIndex>) -> Result<()> {
        if let Some(e) = self.uncaptured.lock().unwrap().take() {
            return Err(Error::Gpu(e));
        }
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: index,
                timeout: Some(self.timeout),
            })
            .map(|_| ())
            .map_err(|e| match e {
                wgpu::PollError::Timeout => Error::Gpu(format!(
                    "device did not finish within {:?} (raise {TIMEOUT_ENV} if it is just slow)",
                    self.timeout
                )),
                other => Error::Gpu(format!("device poll failed: {other}")),
            })
    }

    /// Wait (bounded) until all submitted work is done.
    pub fn wait_idle(&self) -> Result<()> {
        self.wait(None)
    }

    /// Copy the first `words` u32 of `buffer` back to the host (bounded wait).
    pub fn read_words(&self, buffer: &wgpu::Buffer, words: usize) -> Result<Vec<u32>> {
        let pending = self.start_read(buffer, words);
        self.finish_read(pending)
    }

    /// Begin copying the first `words` u32 of `buffer` back to the host: the copy is submitted
    /// after the work submitted before (none of it waited for), and the staging buffer's
    /// mapping requested. [`Self::finish_read`] waits for it, so a caller can record and submit
    /// more work in between (the next group of a request, while this one's colours come back).
    pub fn start_read(&self, buffer: &wgpu::Buffer, words: usize) -> PendingRead {
        let size = (words * 4) as u64;
        let timer = std::time::Instant::now();
        let kept = self.readback.lock().unwrap().take();
        let staging = match kept {
            Some(b) if b.size() >= size.max(4) => b,
            _ => self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: size
                    .max(4)
                    .next_power_of_two()
                    .min(REUSED_READBACK_BYTES)
                    .max(size.max(4)),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("readback"),
            });
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, Some(size.max(4)));
        let submission = self.queue.submit(Some(encoder.finish()));
        let (tx, mapped) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        PendingRead {
            staging,
            words,
            submission,
            mapped,
            started: timer,
        }
    }

    /// Wait (bounded) for a read begun by [`Self::start_read`] and copy its words out.
    pub fn finish_read(&self, read: PendingRead) -> Result<Vec<u32>> {
        let PendingRead {
            staging,
            words,
            submission,
            mapped,
            started,
        } = read;
        let size = (words * 4) as u64;
        let timer = std::time::Instant::now();
        self.wait(Some(submission))?;
        let copied = timer.elapsed();
        // The poll that saw the copy done maps the buffer and runs its callback. Only if it has
        // not (yet) does this wait for all submitted work: work submitted after the copy (the
        // next group of a request) must not be waited for, or the caller's use of these
        // colours could not overlap it.
        let outcome = match mapped.try_recv() {
            Ok(outcome) => outcome,
            Err(_) => {
                self.wait(None)?;
                mapped
                    .recv_timeout(self.timeout)
                    .map_err(|_| Error::Gpu("buffer mapping never completed".into()))?
            }
        };
        outcome.map_err(|e| Error::Gpu(format!("buffer mapping failed: {e}")))?;
        let view = staging
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("buffer mapping failed: {e}")))?;
        let mapped = timer.elapsed();
        // Copied out in parallel: one thread reads mapped memory at 1-2 GB/s here (measured on
        // an H100's driver), so a large read would be bound by the copy.
        const CHUNK: usize = 1 << 18;
        let src = bytemuck::cast_slice::<u8, u32>(&view[..size as usize]);
        let out = if src.len() <= CHUNK {
            // One chunk: copied straight into a new vector, not into zeroes first (a warm
            // cut's 1 MiB of colours).
            src.to_vec()
        } else {
            use rayon::prelude::*;
            let mut out = vec![0u32; words];
            out.par_chunks_mut(CHUNK)
                .zip(src.par_chunks(CHUNK))
                .for_each(|(d, s)| d.copy_from_slice(s));
            out
        };
        drop(view);
        staging.unmap();
        if staging.size() <= REUSED_READBACK_BYTES {
            *self.readback.lock().unwrap() = Some(staging);
        }
        tracing::debug!(
            "read back {:.1} MiB: queued work and copy {:.1} ms, map {:.1} ms, to host {:.1} ms \
             (queued {:.1} ms before)",
            size as f64 / (1 << 20) as f64,
            copied.as_secs_f64() * 1e3,
            (mapped - copied).as_secs_f64() * 1e3,
            (timer.elapsed() - mapped).as_secs_f64() * 1e3,
            (timer - started).as_secs_f64() * 1e3
        );
        Ok(out)
    }

    /// Run `f` inside validation and out-of-memory error scopes; GPU errors become `Error::Gpu`.
    pub fn checked<T>(&self, what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let result = f();
        let v = pollster::block_on(validation.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = v.or(o) {
            return Err(Error::Gpu(format!("{what}: {e}")));
        }
        result
    }
}

/// A read-back under way ([`GpuContext::start_read`]): its staging buffer, the copy's
/// submission and the mapping's outcome to come.
pub struct PendingRead {
    staging: wgpu::Buffer,
    words: usize,
    submission: wgpu::SubmissionIndex,
    mapped: std::sync::mpsc::Receiver<std::result::Result<(), wgpu::BufferAsyncError>>,
    started: std::time::Instant,
}

/// The piece size of [`GpuContext::storage_buffer_in_pieces`].
pub const UPLOAD_PIECE_BYTES: usize = 4 << 20;

/// Split `total` items of `bytes_per_item` bytes into consecutive ranges each at most
/// `max_bytes` long (at least one item per range).
pub fn chunk_ranges(total: usize, bytes_per_item: u64, max_bytes: u64) -> Vec<Range<usize>> {
    let per = (max_bytes / bytes_per_item.max(1)).max(1) as usize;
    (0..total.div_ceil(per))
        .map(|i| i * per..((i + 1) * per).min(total))
        .collect()
}

/// The least the kernels need of a device: 64-thread workgroups, 65535 workgroups per grid
/// row, five storage and two uniform buffers per kernel, the `correct` kernel's projection
/// weights in one uniform binding, and storage bindings of at least 16 MiB (larger work is split
/// to the device's own limit).
pub fn required_limits() -> wgpu::Limits {
    wgpu::Limits {
        max_compute_workgroup_size_x: WORKGROUP_SIZE,
        max_compute_invocations_per_workgroup: WORKGROUP_SIZE,
        max_compute_workgroups_per_dimension: 65535,
        max_storage_buffers_per_shader_stage: 5,
        max_uniform_buffers_per_shader_stage: 2,
        max_uniform_buffer_binding_size: (super::projection_weights::PROJECTION_VECTORS * 16)
            as u64,
        max_storage_buffer_binding_size: 16 << 20,
        ..wgpu::Limits::downlevel_webgl2_defaults()
    }
}

/// The limits the kernels depend on (the rest of [`required_limits`] is what wgpu asks of any
/// device, which an application's device already met).
const KERNEL_LIMITS: [&str; 7] = [
    "max_compute_workgroup_size_x",
    "max_compute_invocations_per_workgroup",
    "max_compute_workgroups_per_dimension",
    "max_storage_buffers_per_shader_stage",
    "max_uniform_buffers_per_shader_stage",
    "max_uniform_buffer_binding_size",
    "max_storage_buffer_binding_size",
];

/// The first of [`KERNEL_LIMITS`] where `limits` falls short of [`required_limits`], named,
/// with both values (compared by wgpu, which knows each limit's direction).
pub fn missing_limit(limits: &wgpu::Limits) -> Option<String> {
    let mut first = None;
    required_limits().check_limits_with_fail_fn(limits, false, |name, want, have| {
        if first.is_none() && KERNEL_LIMITS.contains(&name) {
            first = Some(format!("its limit {name} is {have}; the kernels need {want}"));
        }
    });
    first
}

/// Workgroup counts (x, y) and the thread stride of a row for `threads` threads of a 1D kernel,
/// using y when x would pass the 65535-workgroup limit.
pub fn dispatch_grid(threads: u32) -> (u32, u32, u32) {
    let groups = threads.div_ceil(WORKGROUP_SIZE).max(1);
    let x = groups.min(65535);
    let y = groups.div_ceil(x);
    (x, y, x * WORKGROUP_SIZE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_cover_everything_within_the_limit() {
        let r = chunk_ranges(10, 8, 24);
        assert_eq!(r, vec![0..3, 3..6, 6..9, 9..10]);
        assert_eq!(chunk_ranges(5, 100, 10), vec![0..1, 1..2, 2..3, 3..4, 4..5]);
        assert!(chunk_ranges(0, 4, 16).is_empty());
    }

    #[test]
    fn grid_has_enough_threads() {
        for t in [1u32, 64, 65, 65535 * 64, 65535 * 64 + 1, 10_000_000] {
            let (x, y, stride) = dispatch_grid(t);
            assert!(x <= 65535 && (x * y) as u64 * 64 >= t as u64);
            assert_eq!(stride, x * 64);
        }
    }
}
