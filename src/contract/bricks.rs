//! The brick ABI both backends share: a level's state is stored in bricks of 4^3 voxels, a
//! voxel's slot is its brick's slot times 64 plus its index inside the brick (x fastest), and a
//! brick table maps brick coordinates to slots ([`ABSENT`] where a brick is not stored).

/// Brick edge in voxels (a power of two: positions split into brick and local index by shifts).
pub const BRICK: i32 = 4;
/// Voxels per brick.
pub const BRICK_VOXELS: u32 = 64;
/// Table entry of a brick that is not stored.
pub const ABSENT: u32 = u32::MAX;

/// Brick coordinates (voxel position >> 2).
pub type Brick = [i32; 3];

pub fn brick_of(p: [i32; 3]) -> Brick {
    p.map(|v| v >> 2)
}

/// Index of a voxel inside its brick: x fastest.
pub fn local_index(p: [i32; 3]) -> u32 {
    (((p[2] & 3) * 16 + (p[1] & 3) * 4) + (p[0] & 3)) as u32
}

/// The voxel at `local` in brick `b`.
pub fn voxel_of(b: Brick, local: u32) -> [i32; 3] {
    let l = local as i32;
    [
        b[0] * BRICK + (l & 3),
        b[1] * BRICK + ((l >> 2) & 3),
        b[2] * BRICK + (l >> 4),
    ]
}
