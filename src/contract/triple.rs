//! Exemplar coordinates as the kernels store them: a pixel (x, y) packed into one word, and a
//! voxel's triple of such coordinates, one per exemplar (Ex, Ey, Ez; see `analysis::frame` for
//! the frame they are taken in).

/// "No coordinate": unused candidate slots.
pub const NO_COORD: u32 = u32::MAX;

/// Pack an exemplar pixel coordinate (x < 65536, y < 65536).
#[inline]
pub fn pack(x: u32, y: u32) -> u32 {
    x | (y << 16)
}

/// Unpack a coordinate made by [`pack`].
#[inline]
pub fn unpack(c: u32) -> (u32, u32) {
    (c & 0xFFFF, c >> 16)
}

/// The exemplar that follows `a` cyclically.
#[inline]
pub fn next(a: usize) -> usize {
    (a + 1) % 3
}

/// Rotate a triple stored for exemplar 0 of a shared analysis into the triple of the same
/// 3-neighbourhood seen from exemplar `a` (see the `analysis::frame` module comment): `set_a[p] = rot^a(set_0[p])`.
#[inline]
pub fn rotate_from_shared(t: [u32; 3], a: usize) -> [u32; 3] {
    match a {
        0 => t,
        // (p, b, c) in set 0 at p  ->  (c, p, b) in set 1 at p
        1 => [t[2], t[0], t[1]],
        _ => [t[1], t[2], t[0]],
    }
}
