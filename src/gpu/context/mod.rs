//! `GpuContext`: one wgpu device chosen by name filter, with bounded waits and helpers to split
//! work that exceeds the adapter's storage-binding limit. Its parts: the driver settings a
//! process starts with (`driver_env`), the pipeline cache (`pipelines`), buffer creation and
//! uploads (`buffers`) and read-backs (`readback`).

pub mod buffers;
mod driver_env;
mod pipelines;
mod readback;

pub use buffers::chunk_ranges;
pub use driver_env::{prepare_driver_environment_for, user_driver_environment, DriverUse};
pub use readback::PendingRead;

use crate::error::{Error, Result};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

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

/// The longest `SOLIDSYNTH_GPU_TIMEOUT_S` taken, in seconds (a day).
const MAX_TIMEOUT_S: f64 = 86_400.0;

impl GpuOptions {
    /// Defaults, with the adapter filter and timeout taken from the environment when set.
    pub fn from_env() -> Self {
        let mut o = GpuOptions {
            adapter_filter: std::env::var(ADAPTER_ENV).ok().filter(|s| !s.is_empty()),
            ..GpuOptions::default()
        };
        if let Ok(text) = std::env::var(TIMEOUT_ENV) {
            // A day at most: past that a submission is not waited for, it has hung.
            match text.trim().parse::<f64>() {
                Ok(s) if s > 0.0 && s <= MAX_TIMEOUT_S => o.timeout = Duration::from_secs_f64(s),
                _ => {
                    // Options are read for every device a command opens: one warning.
                    static WARNED: std::sync::Once = std::sync::Once::new();
                    WARNED.call_once(|| {
                        tracing::warn!(
                            "{TIMEOUT_ENV}={text} ignored: not a number of seconds in (0, \
                             {MAX_TIMEOUT_S}]"
                        )
                    });
                }
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
                // A name that matches nothing is the user's input, not a failure of the device.
                Error::invalid(
                    format!(
                        "--adapter {}",
                        opts.adapter_filter.as_deref().unwrap_or("")
                    ),
                    format!(
                        "no adapter matches (from --adapter or {ADAPTER_ENV}); available: {}",
                        names.join(", ")
                    ),
                )
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
    /// ([`required_limits`]). Nothing process-wide is changed, but the device's
    /// uncaptured-error handler (wgpu keeps one per device) becomes the engine's: a GPU error
    /// raised outside an error scope, the application's own included, is then reported by the
    /// engine's next wait as [`Error::Gpu`] instead of reaching a handler the application set
    /// before, and wgpu's default handler (which panics) no longer runs. An application that
    /// sets its own handler again after this call gets its errors back, and the engine's
    /// errors outside scopes (out of memory while allocating a buffer, for one) with them.
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
        let device_max = limits.max_storage_buffer_binding_size;
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
        let index = self.checked("submission", || Ok(self.queue.submit(Some(encoder.finish()))))?;
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
