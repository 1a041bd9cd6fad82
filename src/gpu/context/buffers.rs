//! Buffers: uploads (whole, in pieces, from parts), uniforms, device-filled states and
//! sentinel-filled outputs; and the split of work over the storage-binding limit.

use super::GpuContext;
use crate::error::{Error, Result};
use std::ops::Range;
use wgpu::util::DeviceExt;

impl GpuContext {
    /// A read-only storage buffer holding `bytes` (padded to 4 bytes, at least 4).
    pub fn storage_buffer(&self, label: &str, bytes: &[u8]) -> wgpu::Buffer {
        // (Copied to pad only when needed: most uploads are whole words, some of them large.)
        let padded;
        let contents = if bytes.len().is_multiple_of(4) && !bytes.is_empty() {
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
