//! `synth --triples`: the finest-level coordinate triples, written slab by slab beside the
//! volume (layout: docs/formats.md, "The triples file").

use crate::io::atomic;
use std::path::Path;

/// Magic of the `--triples` file: then version (1), nx, ny, nz, exemplar width and height (u32
/// LE), then per voxel (x fastest) three u32: packed coordinates x | y << 16 in Ex, Ey, Ez.
pub const TRIPLES_MAGIC: &[u8; 8] = b"SSTRIPLE";

/// The `--triples` file, written slab by slab like the volume.
pub(super) struct TriplesWriter {
    file: atomic::PendingFile,
    words_left: u64,
}

impl TriplesWriter {
    pub(super) fn create(path: &Path, dims: [u32; 3], exemplar: [u32; 2]) -> crate::Result<Self> {
        let mut file = atomic::PendingFile::create(path)?;
        let mut header = TRIPLES_MAGIC.to_vec();
        for v in [1u32, dims[0], dims[1], dims[2], exemplar[0], exemplar[1]] {
            header.extend_from_slice(&v.to_le_bytes());
        }
        file.write_all(&header)?;
        Ok(TriplesWriter {
            file,
            words_left: dims.iter().map(|&d| d as u64).product::<u64>() * 3,
        })
    }

    pub(super) fn write(&mut self, triples: &[u32]) -> crate::Result<()> {
        self.words_left -= triples.len() as u64;
        let bytes: Vec<u8> = triples.iter().flat_map(|t| t.to_le_bytes()).collect();
        self.file.write_all(&bytes)
    }

    pub(super) fn finish(self) -> atomic::PendingFile {
        assert_eq!(self.words_left, 0, "triples incomplete");
        self.file
    }
}
