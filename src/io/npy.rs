//! NumPy `.npy` volumes: `uint8`, shape (Z, Y, X, C), C order, so `numpy.load` gives the array
//! as is. Format 1.0 (<https://numpy.org/doc/stable/reference/generated/numpy.lib.format.html>):
//! the magic `\x93NUMPY`, version 1.0, a little-endian u16 header length, then a Python dict
//! literal padded with spaces and ending in a newline so the data starts at a multiple of 64
//! bytes; the data follow, exactly the NRRD order of a volume (channel fastest, then x, y, z).
//! Written here rather than through a crate: the header is a few lines and a volume is streamed
//! slab by slab, which the crates' whole-array writers do not do.

use crate::error::Result;
use crate::io::atomic::PendingFile;
use crate::io::slab_order::SlabOrder;
use crate::volume::Volume;
use std::path::Path;

/// The header of a (Z, Y, X, C) `uint8` array.
pub fn header(dims: [u32; 3], channels: u32) -> Vec<u8> {
    let dict = format!(
        "{{'descr': '|u1', 'fortran_order': False, 'shape': ({}, {}, {}, {}), }}",
        dims[2], dims[1], dims[0], channels
    );
    // Magic (6) + version (2) + length (2) + dict + padding + newline, to a multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let padded = unpadded.div_ceil(64) * 64;
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&((padded - 10) as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.resize(padded - 1, b' ');
    out.push(b'\n');
    out
}

/// A volume written slab by slab along z; atomic as [`crate::io::nrrd::SlabWriter`].
pub struct SlabWriter {
    file: PendingFile,
    order: SlabOrder,
}

impl SlabWriter {
    pub fn create(path: &Path, dims: [u32; 3], channels: u32) -> Result<SlabWriter> {
        let mut file = PendingFile::create(path)?;
        file.write_all(&header(dims, channels))?;
        Ok(SlabWriter {
            file,
            order: SlabOrder::new(dims, channels)?,
        })
    }

    /// The next `slab.nz` z slices.
    pub fn write_slab(&mut self, slab: &Volume) -> Result<()> {
        self.order.advance(slab)?;
        self.file.write_all(&slab.data)
    }

    pub fn finish(self) -> Result<PendingFile> {
        self.order.finish()?;
        Ok(self.file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_is_aligned_and_names_the_shape() {
        let h = header([5, 6, 7], 3);
        assert_eq!(h.len() % 64, 0);
        assert_eq!(&h[..8], b"\x93NUMPY\x01\x00");
        assert_eq!(u16::from_le_bytes([h[8], h[9]]) as usize, h.len() - 10);
        let text = std::str::from_utf8(&h[10..]).unwrap();
        assert!(text.contains("'shape': (7, 6, 5, 3)"));
        assert!(text.ends_with('\n'));
    }
}
