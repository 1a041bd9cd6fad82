//! The flipbook layout of a volume: all z slices in one image, a grid of [`columns`] x
//! nz / [`columns`] tiles, row-major (slice z at column z % cols, row z / cols), x along each
//! tile's rows. This is the layout Unity and Unreal import as a 3D texture: both take the depth
//! as columns x rows, so the grid holds exactly nz tiles (an empty tile would import as an extra
//! slice). [`from_image`] reads it back, so the layout is round-trip tested rather than only
//! described.

use crate::error::{Error, Result};
use crate::volume::Volume;

/// Columns of the grid for `nz` slices: the smallest divisor of nz that is at least its square
/// root, so the grid is as square as nz's factors allow and never taller than wide (64 slices:
/// 8 x 8; 32: 8 x 4; 128: 16 x 8; a prime count: one row, nz^2 pixels wide, past the 16384
/// pixels a game engine imports once nz > 128).
pub fn columns(nz: u32) -> u32 {
    (1..=nz.max(1))
        .find(|&c| nz.is_multiple_of(c) && u64::from(c) * u64::from(c) >= u64::from(nz))
        .unwrap_or(1)
}

fn rgba(p: &[u8]) -> image::Rgba<u8> {
    match p.len() {
        1 => image::Rgba([p[0], p[0], p[0], 255]),
        2 => image::Rgba([p[0], p[0], p[0], p[1]]),
        3 => image::Rgba([p[0], p[1], p[2], 255]),
        _ => image::Rgba([p[0], p[1], p[2], p[3]]),
    }
}

/// All z slices in one RGBA image (gray volumes are replicated to RGB, opaque).
pub fn to_image(v: &Volume) -> image::RgbaImage {
    let cols = columns(v.nz);
    let rows = v.nz / cols;
    let mut img = image::RgbaImage::new(cols * v.nx, rows * v.ny);
    for z in 0..v.nz {
        let (ox, oy) = ((z % cols) * v.nx, (z / cols) * v.ny);
        for y in 0..v.ny {
            for x in 0..v.nx {
                img.put_pixel(ox + x, oy + y, rgba(v.at(x, y, z)));
            }
        }
    }
    img
}

/// The volume as RGBA bytes, x fastest then y then z: what WebGL2's `texImage3D` takes.
pub fn rgba_bytes(v: &Volume) -> Vec<u8> {
    let c = v.channels as usize;
    v.data.chunks_exact(c).flat_map(|p| rgba(p).0).collect()
}

/// Read a flipbook of `nz` slices back into a volume of `channels` (1, 3 or 4) channels; the tile
/// size follows from the image size and the grid. Refuses images whose size does not fit.
pub fn from_image(img: &image::RgbaImage, nz: u32, channels: u32) -> Result<Volume> {
    if nz == 0 || ![1, 3, 4].contains(&channels) {
        return Err(Error::invalid(
            "flipbook",
            "needs at least one slice and 1, 3 or 4 channels",
        ));
    }
    let cols = columns(nz);
    let rows = nz / cols;
    if !img.width().is_multiple_of(cols) || !img.height().is_multiple_of(rows) || img.width() == 0 {
        return Err(Error::invalid(
            "flipbook",
            format!(
                "a {}x{} image is not a grid of {cols}x{rows} tiles",
                img.width(),
                img.height()
            ),
        ));
    }
    let (nx, ny) = (img.width() / cols, img.height() / rows);
    let mut v = Volume::new(nx, ny, nz, channels);
    for z in 0..nz {
        let (ox, oy) = ((z % cols) * nx, (z / cols) * ny);
        for y in 0..ny {
            for x in 0..nx {
                let p = img.get_pixel(ox + x, oy + y).0;
                v.at_mut(x, y, z).copy_from_slice(&p[..channels as usize]);
            }
        }
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn volume(nx: u32, ny: u32, nz: u32, channels: u32) -> Volume {
        let mut v = Volume::new(nx, ny, nz, channels);
        for (i, b) in v.data.iter_mut().enumerate() {
            *b = (i * 31 % 253) as u8;
        }
        v
    }

    #[test]
    fn round_trips_any_shape() {
        for (nx, ny, nz, c) in [(4, 3, 5, 3), (8, 8, 16, 4), (2, 5, 1, 1), (3, 3, 10, 3)] {
            let v = volume(nx, ny, nz, c);
            let img = to_image(&v);
            let cols = columns(nz);
            assert_eq!(img.dimensions(), (cols * nx, nz / cols * ny));
            assert_eq!(from_image(&img, nz, c).unwrap(), v, "{nx}x{ny}x{nz}x{c}");
        }
    }

    #[test]
    fn slice_z_is_the_tile_at_column_z_mod_cols() {
        let v = volume(4, 4, 6, 3);
        let img = to_image(&v);
        // 6 slices: 3 columns, 2 rows; slice 4 is at column 1, row 1.
        assert_eq!(img.dimensions(), (12, 8));
        assert_eq!(&img.get_pixel(4 + 2, 4 + 1).0[..3], v.at(2, 1, 4));
        // A perturbed image no longer reads back equal (the comparison can fail).
        let mut bad = img.clone();
        bad.get_pixel_mut(0, 0).0[0] ^= 1;
        assert_ne!(from_image(&bad, 6, 3).unwrap(), v);
        assert!(from_image(&img, 7, 3).is_err());
    }

    #[test]
    fn the_grid_holds_exactly_one_tile_per_slice() {
        for (nz, cols) in [
            (1, 1),
            (5, 5),
            (12, 4),
            (32, 8),
            (64, 8),
            (128, 16),
            (256, 16),
            (512, 32),
        ] {
            assert_eq!(columns(nz), cols, "{nz} slices");
        }
        for nz in 1..600u32 {
            let c = columns(nz);
            assert_eq!(nz % c, 0, "{nz} slices in {c} columns");
            assert!(c * c >= nz && (nz / c) <= c, "{nz}: {c} columns");
        }
    }
}
