//! The limits every front end (the command line, the Python package) puts on requests, checked
//! with the command line's messages, so a bad value reads the same wherever it was given.

use crate::error::{Error, Result};
use crate::lazy::Box3;

/// Largest side of a box synthesized whole (`synth --size`, `region --box`, `tileable`).
pub const MAX_BOX_SIDE: u32 = 2048;

pub use crate::lazy::plan::COORDINATE_LIMIT;

/// The largest cube a surface is fitted into (`surface --resolution`), in voxels.
pub const MAX_SURFACE_RESOLUTION: u32 = 1 << 20;

/// A surface's `--resolution`: 1..=[`MAX_SURFACE_RESOLUTION`].
pub fn check_surface_resolution(resolution: u32) -> Result<u32> {
    if !(1..=MAX_SURFACE_RESOLUTION).contains(&resolution) {
        return Err(Error::invalid(
            format!("--resolution {resolution}"),
            format!("must be 1..={MAX_SURFACE_RESOLUTION}"),
        ));
    }
    Ok(resolution)
}

/// Largest side of a planar cut, in pixels.
pub const MAX_CUT_SIZE: u32 = crate::lazy::cut::MAX_CUT_SIZE;

/// The group edges `--max-group` accepts.
pub use crate::lazy::MAX_GROUP_SIDES;

/// The half-open box [lo, hi), named `what` in errors (`--box ...`): corners within
/// [`COORDINATE_LIMIT`], every side positive and at most `max_side` voxels.
pub fn checked_box(what: &str, lo: [i64; 3], hi: [i64; 3], max_side: i64) -> Result<Box3> {
    if lo
        .iter()
        .chain(&hi)
        .any(|c| c.unsigned_abs() > COORDINATE_LIMIT as u64)
    {
        return Err(Error::invalid(
            what,
            format!("coordinates must lie within +-{COORDINATE_LIMIT}"),
        ));
    }
    for a in 0..3 {
        if hi[a] <= lo[a] {
            return Err(Error::invalid(
                what,
                format!("{0}1 must be greater than {0}0", ["X", "Y", "Z"][a]),
            ));
        }
        if hi[a] - lo[a] > max_side {
            return Err(Error::invalid(
                what,
                format!("each side must be at most {max_side} voxels"),
            ));
        }
    }
    Ok(Box3::new(lo.map(|c| c as i32), hi.map(|c| c as i32)))
}

/// A whole box's side (`synth --size`, `tileable`), named `what`: 8..=[`MAX_BOX_SIDE`].
pub fn check_size(what: &str, size: i64) -> Result<u32> {
    if !(8..=MAX_BOX_SIDE as i64).contains(&size) {
        return Err(Error::invalid(what, format!("must be 8..={MAX_BOX_SIDE}")));
    }
    Ok(size as u32)
}

/// A cut's side in pixels, named `what`: 1..=[`MAX_CUT_SIZE`].
pub fn check_cut_size(what: &str, size: i64) -> Result<u32> {
    if !(1..=MAX_CUT_SIZE as i64).contains(&size) {
        return Err(Error::invalid(what, format!("must be 1..={MAX_CUT_SIZE}")));
    }
    Ok(size as u32)
}

/// A `--max-group` edge: within [`MAX_GROUP_SIDES`] (the synthesizer's own check, which
/// `SynthOptions::validate` makes).
pub fn check_max_group(side: u32) -> Result<u32> {
    crate::lazy::SynthOptions {
        max_group: Some(side),
        ..Default::default()
    }
    .validate()?;
    Ok(side)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_sizes_and_groups_are_checked_with_the_command_lines_messages() {
        let b = checked_box("--box b", [-3, 0, 5], [5, 2048, 6], 2048).unwrap();
        assert_eq!(b, Box3::new([-3, 0, 5], [5, 2048, 6]));
        let message = |r: Result<Box3>| r.unwrap_err().to_string();
        assert!(message(checked_box("--box b", [0; 3], [0, 1, 1], 2048))
            .contains("X1 must be greater than X0"));
        assert!(message(checked_box("--box b", [0; 3], [1, 2049, 1], 2048))
            .contains("each side must be at most 2048 voxels"));
        assert!(message(checked_box(
            "--box b",
            [0; 3],
            [1, 1, (1 << 28) + 1],
            1 << 30
        ))
        .contains("within +-268435456"));
        assert_eq!(check_size("--size 8", 8).unwrap(), 8);
        assert!(check_size("--size 7", 7).is_err());
        assert!(check_cut_size("--size 4097", 4097).is_err());
        assert!(check_max_group(3).is_err() && check_max_group(512).is_ok());
    }
}
