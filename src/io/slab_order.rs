//! The bookkeeping every streaming volume writer shares: slabs of z slices must continue the
//! volume (same x and y extents and channels, not past its depth), and a finished file must
//! hold every slice.

use crate::volume::Volume;

/// Where a volume written slab by slab along z stands.
pub struct SlabOrder {
    dims: [u32; 3],
    channels: u32,
    slices_written: u32,
}

impl SlabOrder {
    pub fn new(dims: [u32; 3], channels: u32) -> SlabOrder {
        SlabOrder {
            dims,
            channels,
            slices_written: 0,
        }
    }

    /// Count `slab`, which must continue the volume (a caller's bug otherwise).
    pub fn advance(&mut self, slab: &Volume) {
        assert!(
            slab.nx == self.dims[0]
                && slab.ny == self.dims[1]
                && slab.channels == self.channels
                && self.slices_written + slab.nz <= self.dims[2],
            "slab {:?} x {} does not continue a volume {:?} x {} at z {}",
            slab.dims(),
            slab.channels,
            self.dims,
            self.channels,
            self.slices_written
        );
        self.slices_written += slab.nz;
    }

    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    pub fn channels(&self) -> u32 {
        self.channels
    }

    /// Slices written so far.
    pub fn slices_written(&self) -> u32 {
        self.slices_written
    }

    /// Check that every slice arrived.
    pub fn finish(&self) {
        assert_eq!(self.slices_written, self.dims[2], "volume incomplete");
    }
}
