//! The bookkeeping every streaming volume writer shares: slabs of z slices must continue the
//! volume (same x and y extents and channels, not past its depth), and a finished file must
//! hold every slice.

use crate::error::{Error, Result};
use crate::volume::Volume;

/// Where a volume written slab by slab along z stands.
pub struct SlabOrder {
    dims: [u32; 3],
    channels: u32,
    slices_written: u32,
}

/// Refuse a volume no format holds: a side of zero voxels, or other than 1 to 4 channels.
pub fn check_dims(dims: [u32; 3], channels: u32) -> Result<()> {
    if dims.contains(&0) || !(1..=4).contains(&channels) {
        return Err(Error::invalid(
            "volume",
            format!(
                "is {}x{}x{} voxels of {channels} channels; a volume has sides of at least one \
                 voxel and 1 to 4 channels",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    Ok(())
}

impl SlabOrder {
    /// A volume of `dims` voxels of `channels` bytes, refused where no format holds it
    /// ([`check_dims`]).
    pub fn new(dims: [u32; 3], channels: u32) -> Result<SlabOrder> {
        check_dims(dims, channels)?;
        Ok(SlabOrder {
            dims,
            channels,
            slices_written: 0,
        })
    }

    /// Count `slab`, which must continue the volume and hold the bytes its sizes say.
    pub fn advance(&mut self, slab: &Volume) -> Result<()> {
        let continues = slab.nx == self.dims[0]
            && slab.ny == self.dims[1]
            && slab.channels == self.channels
            && u64::from(self.slices_written) + u64::from(slab.nz) <= u64::from(self.dims[2]);
        if !continues {
            return Err(Error::invalid(
                "slab",
                format!(
                    "{:?} x {} channels does not continue a volume {:?} x {} at z {}",
                    slab.dims(),
                    slab.channels,
                    self.dims,
                    self.channels,
                    self.slices_written
                ),
            ));
        }
        slab.check("slab")?;
        self.slices_written += slab.nz;
        Ok(())
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
    pub fn finish(&self) -> Result<()> {
        if self.slices_written != self.dims[2] {
            return Err(Error::invalid(
                "volume",
                format!(
                    "{} of its {} z slices were written; the file is incomplete",
                    self.slices_written, self.dims[2]
                ),
            ));
        }
        Ok(())
    }
}
