//! Read-backs: a device buffer's words copied to the host through a staging buffer (one kept
//! for the next small read), begun and finished apart so work can be queued in between.

use super::GpuContext;
use crate::error::{Error, Result};

/// Read-back staging buffers up to this size are kept for the next read; larger reads (whole
/// volumes) allocate their own, so memory is not held after them.
const REUSED_READBACK_BYTES: u64 = 16 << 20;

impl GpuContext {
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
