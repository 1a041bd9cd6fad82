//! Dispatch of `wgsl/bucket_accumulate.wgsl` (CPU reference: `src/cpu/bucket_accumulate.rs`).

use super::context::{dispatch_grid, GpuContext};
use crate::contract::buckets::Buckets;
use crate::contract::uniforms::BucketParams;
use crate::error::{Error, Result};

/// Same result as [`crate::cpu::bucket_accumulate::bucket_accumulate`], bit for bit.
#[cfg(any(test, feature = "internals"))]
pub fn bucket_accumulate(
    gpu: &GpuContext,
    samples: &[u32],
    voxels: usize,
    clusters: u32,
    channels: u32,
) -> Result<Buckets> {
    bucket_accumulate_parts(gpu, &[samples], voxels, clusters, channels)
}

/// [`bucket_accumulate`] of the samples `parts` hold end to end (each part whole samples).
/// Samples beyond one storage binding go in several buffers, each dispatched in turn: every
/// pass sees all of them, so the buckets are the same.
pub fn bucket_accumulate_parts(
    gpu: &GpuContext,
    parts: &[&[u32]],
    voxels: usize,
    clusters: u32,
    channels: u32,
) -> Result<Buckets> {
    if clusters == 0 || clusters > 32 {
        return Err(Error::invalid("clusters", "must be 1..=32"));
    }
    let stride = 2 + channels as usize;
    let count_words = voxels * clusters as usize;
    let sum_words = voxels * 2 * (1 + channels as usize);
    let max_words = (gpu.max_binding_bytes() / 4) as usize;
    if count_words.max(sum_words) > max_words || max_words < stride {
        return Err(Error::Gpu(format!(
            "bucket_accumulate: {voxels} voxels' buckets exceed one storage binding"
        )));
    }
    let pipeline = gpu.pipeline("bucket_accumulate")?;
    let inputs = split_parts(parts, max_words / stride * stride)
        .iter()
        .map(|chunk| {
            let n = chunk.iter().map(|p| p.len()).sum::<usize>() / stride;
            Ok((gpu.storage_buffer_parts("samples", chunk)?, n))
        })
        .collect::<Result<Vec<_>>>()?;
    let counts = gpu.output_buffer("bucket counts", count_words, 0);
    let sums = gpu.output_buffer("bucket sums", sum_words, 0);
    let dominants = gpu.output_buffer("dominant clusters", voxels, 0);
    let run = |pass: u32, input: &wgpu::Buffer, threads: usize| -> Result<()> {
        let (gx, gy, grid_stride) = dispatch_grid(threads as u32);
        let params = BucketParams {
            samples: threads as u32,
            clusters,
            channels,
            pass_index: pass,
            grid_stride,
            voxels: voxels as u32,
            ..Default::default()
        };
        gpu.checked("bucket_accumulate", || {
            let uniform = gpu.uniform_buffer("bucket params", &params);
            gpu.dispatch_and_wait(
                "bucket_accumulate",
                &pipeline,
                &[&uniform, input, &counts, &sums, &dominants],
                (gx, gy),
            )
        })
    };
    for (input, n) in &inputs {
        run(0, input, *n)?;
    }
    // (Pass 1 reads no samples: any buffer binds there.)
    run(1, &inputs[0].0, voxels)?;
    for (input, n) in &inputs {
        run(2, input, *n)?;
    }
    Ok(Buckets {
        counts: gpu.read_words(&counts, count_words)?,
        sums: gpu.read_words(&sums, sum_words)?,
    })
}

/// `parts` regrouped into chunks of at most `max_words` words (a multiple of the sample
/// stride, as every part's length is), cutting parts where needed; at least one chunk.
fn split_parts<'a>(parts: &[&'a [u32]], max_words: usize) -> Vec<Vec<&'a [u32]>> {
    let mut chunks = vec![Vec::new()];
    let mut room = max_words;
    for part in parts {
        let mut rest = *part;
        while !rest.is_empty() {
            if room == 0 {
                chunks.push(Vec::new());
                room = max_words;
            }
            let (head, tail) = rest.split_at(rest.len().min(room));
            chunks.last_mut().expect("a chunk").push(head);
            room -= head.len();
            rest = tail;
        }
    }
    chunks
}

#[cfg(test)]
mod tests {
    use super::split_parts;

    #[test]
    fn parts_are_cut_into_chunks_of_whole_samples_in_order() {
        let a: Vec<u32> = (0..10).collect();
        let b: Vec<u32> = (10..14).collect();
        let c: Vec<u32> = (14..30).collect();
        let chunks = split_parts(&[&a, &b, &c], 6);
        let sizes: Vec<usize> = chunks
            .iter()
            .map(|ch| ch.iter().map(|p| p.len()).sum())
            .collect();
        assert_eq!(sizes, [6, 6, 6, 6, 6]);
        let joined: Vec<u32> = chunks.concat().concat();
        assert_eq!(joined, (0..30).collect::<Vec<u32>>());
        assert_eq!(split_parts(&[], 6).len(), 1);
    }
}
