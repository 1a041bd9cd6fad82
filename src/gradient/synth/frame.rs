//! Orientation of the three check-point slices (paper 4, Fig. 7 and 9): without a field the
//! slices are the axis planes; a direction field turns them so the exemplar follows it (wood
//! rings around a cylinder axis, strata along a constant direction).

use glam::DVec3;

/// A direction field, given by the user.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Field {
    /// Axis-aligned slices.
    None,
    /// The slices' local z axis is this (constant) direction.
    Constant([f64; 3]),
    /// Cylindrical around an axis of this direction through the solid's centre: local z along
    /// the axis, local x radial (rings of a trunk, a turned vase).
    Cylinder([f64; 3]),
}

impl Field {
    /// Parse `none`, `constant:X,Y,Z` or `cylinder:X,Y,Z`.
    pub fn parse(text: &str) -> Option<Field> {
        let direction = |rest: &str| -> Option<[f64; 3]> {
            let v: Vec<f64> = rest
                .split(',')
                .map(|t| t.trim().parse::<f64>().ok())
                .collect::<Option<_>>()?;
            let v: [f64; 3] = v.try_into().ok()?;
            let len = DVec3::from_array(v).length();
            (len.is_finite() && len > 1e-9).then_some(v)
        };
        match text.split_once(':') {
            None if text == "none" => Some(Field::None),
            Some(("constant", rest)) => direction(rest).map(Field::Constant),
            Some(("cylinder", rest)) => direction(rest).map(Field::Cylinder),
            _ => None,
        }
    }

    /// The local frame (x, y, z axes, orthonormal) at voxel position `p` of a solid whose centre
    /// is `centre`.
    pub fn frame(&self, p: [i32; 3], centre: DVec3) -> Frame {
        match *self {
            Field::None => Frame::IDENTITY,
            Field::Constant(d) => Frame::around(DVec3::from_array(d), None),
            Field::Cylinder(d) => {
                let axis = DVec3::from_array(d).normalize();
                let r = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) - centre;
                let radial = r - axis * r.dot(axis);
                Frame::around(axis, (radial.length() > 0.5).then_some(radial))
            }
        }
    }
}

/// How exemplar patches lie in the three slices: which local axes a patch's columns (U) and
/// rows (V) run along.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SliceAxes {
    /// The crate's frame (`crate::analysis::frame`, and what `eval` compares with): x: (y, z),
    /// y: (z, x), z: (x, y). Used when three slices are matched.
    Cyclic,
    /// x: (y, z), y: (x, z), z: (x, y): the slices orthogonal to x and y share "up" (z), so a
    /// layered exemplar (brick courses, strata) can hold on both. Used when two are matched.
    Upright,
}

impl SliceAxes {
    /// (U, V) axis indices of the slice orthogonal to axis `o`.
    pub fn of(self, o: usize) -> (usize, usize) {
        match (self, o) {
            (_, 0) => (1, 2),
            (SliceAxes::Cyclic, 1) => (2, 0),
            (SliceAxes::Upright, 1) => (0, 2),
            _ => (0, 1),
        }
    }
}

/// Three orthonormal axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame(pub [DVec3; 3]);

impl Frame {
    pub const IDENTITY: Frame = Frame([DVec3::X, DVec3::Y, DVec3::Z]);

    /// Local z along `z`, local x along `x` made orthogonal to it (or the world axis least
    /// aligned with z when none is given).
    fn around(z: DVec3, x: Option<DVec3>) -> Frame {
        let z = z.normalize();
        let hint = x.unwrap_or_else(|| {
            let a = z.abs();
            if a.x <= a.y && a.x <= a.z {
                DVec3::X
            } else if a.y <= a.z {
                DVec3::Y
            } else {
                DVec3::Z
            }
        });
        let x = (hint - z * hint.dot(z)).normalize();
        Frame([x, z.cross(x), z])
    }

    /// The two in-plane axes (U, V) of the slice orthogonal to local axis `o`, as local axis
    /// indices (see [`SliceAxes`]), turned into directions.
    pub fn slice_axes(&self, axes: SliceAxes, o: usize) -> (DVec3, DVec3) {
        let (u, v) = axes.of(o);
        (self.0[u], self.0[v])
    }

    /// True when the frame is the identity (integer sample offsets, no rounding).
    pub fn is_identity(&self) -> bool {
        *self == Frame::IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_parse_and_give_orthonormal_frames() {
        assert_eq!(Field::parse("none"), Some(Field::None));
        assert_eq!(
            Field::parse("constant:0,0,2"),
            Some(Field::Constant([0.0, 0.0, 2.0]))
        );
        assert_eq!(
            Field::parse("cylinder:1,1,0"),
            Some(Field::Cylinder([1.0, 1.0, 0.0]))
        );
        for bad in [
            "",
            "constant",
            "constant:0,0,0",
            "spiral:1,0,0",
            "cylinder:1,2",
            "constant:a,b,c",
        ] {
            assert_eq!(Field::parse(bad), None, "{bad}");
        }
        let centre = DVec3::splat(16.0);
        for field in [
            Field::Constant([1.0, 2.0, 3.0]),
            Field::Cylinder([0.0, 0.0, 1.0]),
        ] {
            let f = field.frame([30, 5, 7], centre);
            for i in 0..3 {
                assert!((f.0[i].length() - 1.0).abs() < 1e-12);
                for j in 0..i {
                    assert!(f.0[i].dot(f.0[j]).abs() < 1e-12);
                }
            }
        }
        // Cylinder: local x is radial.
        let f = Field::Cylinder([0.0, 0.0, 1.0]).frame([26, 16, 3], centre);
        assert!((f.0[0] - DVec3::X).length() < 1e-12, "{f:?}");
    }
}
