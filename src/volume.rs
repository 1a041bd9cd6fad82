//! A dense 8-bit volume with interleaved channels, x fastest (the NRRD order).

/// `channels` bytes per voxel; voxel (x, y, z) at ((z * ny + y) * nx + x) * channels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Volume {
    pub nx: u32,
    pub ny: u32,
    pub nz: u32,
    pub channels: u32,
    pub data: Vec<u8>,
}

impl Volume {
    pub fn new(nx: u32, ny: u32, nz: u32, channels: u32) -> Volume {
        Volume {
            nx,
            ny,
            nz,
            channels,
            data: vec![0; nx as usize * ny as usize * nz as usize * channels as usize],
        }
    }

    /// Refuse a volume built by hand whose fields disagree: 1 to 4 channels, and
    /// `nx x ny x nz x channels` bytes of data. `what` names it in the message.
    pub fn check(&self, what: &str) -> crate::Result<()> {
        if !(1..=4).contains(&self.channels) {
            return Err(crate::Error::invalid(
                what,
                format!("has {} channels; volumes have 1 to 4", self.channels),
            ));
        }
        crate::Error::check_held(
            what,
            self.data.len(),
            &self.dims(),
            u64::from(self.channels),
            "bytes",
            || {
                format!(
                    "{}x{}x{} voxels of {} channels take",
                    self.nx, self.ny, self.nz, self.channels
                )
            },
        )
    }

    pub fn dims(&self) -> [u32; 3] {
        [self.nx, self.ny, self.nz]
    }

    fn offset(&self, x: u32, y: u32, z: u32) -> usize {
        assert!(
            x < self.nx && y < self.ny && z < self.nz,
            "voxel ({x}, {y}, {z}) is outside the {}x{}x{} volume",
            self.nx,
            self.ny,
            self.nz
        );
        ((z as usize * self.ny as usize + y as usize) * self.nx as usize + x as usize)
            * self.channels as usize
    }

    /// The channels of voxel (x, y, z).
    ///
    /// # Panics
    /// If the voxel is outside the volume.
    pub fn at(&self, x: u32, y: u32, z: u32) -> &[u8] {
        let i = self.offset(x, y, z);
        &self.data[i..i + self.channels as usize]
    }

    /// The channels of voxel (x, y, z), to change.
    ///
    /// # Panics
    /// If the voxel is outside the volume.
    pub fn at_mut(&mut self, x: u32, y: u32, z: u32) -> &mut [u8] {
        let i = self.offset(x, y, z);
        let c = self.channels as usize;
        &mut self.data[i..i + c]
    }
}

#[cfg(test)]
mod tests {
    use super::Volume;

    #[test]
    #[should_panic(expected = "voxel (4, 0, 0) is outside the 4x2x2 volume")]
    fn a_voxel_past_a_row_is_not_the_next_rows_first() {
        Volume::new(4, 2, 2, 1).at(4, 0, 0);
    }
}
