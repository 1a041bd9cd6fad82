//! The compute pipelines of the kernels, built once per set of `override` constants and
//! cached on the context, several at once where a synthesis is about to need them.

use super::GpuContext;
use crate::error::{Error, Result};
use std::sync::Arc;

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
    Ok(std::borrow::Cow::Borrowed(crate::gpu::shaders::source(name)))
}

impl GpuContext {
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
}
