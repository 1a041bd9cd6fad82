//! The constraints file that shapes the field (JSON), parsed and checked:
//!
//! ```json
//! {
//!   "type": "2-b",                               // "0", "1-a", "1-b", "2-a" or "2-b"
//!   "scale": 0.8,                                // world size of one exemplar cube (default)
//!   "scales": [{"at": [0, 0, 0], "scale": 0.5}], // scale constraints at points
//!   "strokes": [[[0, 0, -1], [0, 0, 1]]],        // polylines: primary (1-a) / secondary (2-*)
//!   "depth": {"inner": [[[0, 0, -0.8], [0, 0, 0.8]]],  // depth 1 strokes
//!             "inner_regions": [{"center": [0, 0, 1], "radius": 0.3}],  // surface painted 1
//!             "outer_regions": [...]}  // surface painted 0 (default: all the rest)
//! }
//! ```

use crate::error::{Error, Result};
use crate::lapped::winding::Winding;
use crate::util::number_text;
use glam::DVec3;
use serde::Deserialize;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureType {
    Isotropic,
    /// 1-a: one axis from strokes.
    Oriented,
    /// 1-b: one axis from the depth field, depth-varying.
    Layered,
    /// 2-a: full tensor (depth gradient + strokes), homogeneous.
    Tensor,
    /// 2-b: full tensor, depth-varying.
    TensorLayered,
}

impl TextureType {
    pub fn parse(s: &str) -> Option<TextureType> {
        Some(match s {
            "0" => TextureType::Isotropic,
            "1-a" => TextureType::Oriented,
            "1-b" => TextureType::Layered,
            "2-a" => TextureType::Tensor,
            "2-b" => TextureType::TensorLayered,
            _ => return None,
        })
    }
    pub fn name(self) -> &'static str {
        match self {
            TextureType::Isotropic => "0",
            TextureType::Oriented => "1-a",
            TextureType::Layered => "1-b",
            TextureType::Tensor => "2-a",
            TextureType::TensorLayered => "2-b",
        }
    }
    pub fn uses_depth(self) -> bool {
        matches!(
            self,
            TextureType::Layered | TextureType::Tensor | TextureType::TensorLayered
        )
    }
    /// Depth is a texture coordinate (and the masks are layered).
    pub fn depth_varying(self) -> bool {
        matches!(self, TextureType::Layered | TextureType::TensorLayered)
    }
    pub(super) fn uses_strokes(self) -> bool {
        matches!(
            self,
            TextureType::Oriented | TextureType::Tensor | TextureType::TensorLayered
        )
    }
    /// A full tensor everywhere (no random axes).
    pub fn full_tensor(self) -> bool {
        matches!(self, TextureType::Tensor | TextureType::TensorLayered)
    }
}

type Polyline = Vec<[f64; 3]>;

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct ScaleFile {
    at: [f64; 3],
    scale: f64,
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct DepthFile {
    #[serde(default)]
    inner: Vec<Polyline>,
    #[serde(default)]
    inner_regions: Vec<RegionFile>,
    #[serde(default)]
    outer_regions: Vec<RegionFile>,
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct RegionFile {
    center: [f64; 3],
    radius: f64,
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct ConstraintsFile {
    #[serde(rename = "type")]
    kind: String,
    scale: Option<f64>,
    #[serde(default)]
    scales: Vec<ScaleFile>,
    #[serde(default)]
    strokes: Vec<Polyline>,
    depth: Option<DepthFile>,
}

/// Validated constraints.
#[derive(Clone, Debug)]
pub struct Constraints {
    pub kind: TextureType,
    pub scale: Option<f64>,
    pub scales: Vec<(DVec3, f64)>,
    pub strokes: Vec<Vec<DVec3>>,
    pub inner: Vec<Vec<DVec3>>,
    /// Surface regions of depth 1: balls (centre, radius) selecting boundary vertices.
    pub inner_regions: Vec<(DVec3, f64)>,
    /// Surface regions of depth 0; when given, the rest of the surface is unconstrained.
    pub outer_regions: Vec<(DVec3, f64)>,
}

impl Constraints {
    /// Type 0, no constraints (what `lapped fill` uses without `--field`).
    pub fn isotropic() -> Constraints {
        Constraints {
            kind: TextureType::Isotropic,
            scale: None,
            scales: Vec::new(),
            strokes: Vec::new(),
            inner: Vec::new(),
            inner_regions: Vec::new(),
            outer_regions: Vec::new(),
        }
    }

    pub fn load(path: &Path) -> Result<Constraints> {
        let bytes = crate::io::input::read(path)?;
        Self::parse(&bytes, &path.display().to_string())
    }

    /// Parse and check the file's own consistency; `what` names it in errors.
    pub fn parse(bytes: &[u8], what: &str) -> Result<Constraints> {
        let file: ConstraintsFile = serde_json::from_slice(bytes)
            .map_err(|e| Error::invalid(what, format!("not a valid constraints file: {e}")))?;
        let kind = TextureType::parse(&file.kind).ok_or_else(|| {
            Error::invalid(
                what,
                format!(
                    "unknown texture type {:?}: expected \"0\", \"1-a\", \"1-b\", \"2-a\" or \"2-b\"",
                    file.kind
                ),
            )
        })?;
        let finite = |p: &[f64; 3]| p.iter().all(|c| c.is_finite());
        let point = |p: &[f64; 3], field: &str| -> Result<DVec3> {
            if finite(p) {
                Ok(DVec3::from_array(*p))
            } else {
                Err(Error::invalid(
                    what,
                    format!("{field}: coordinates must be finite"),
                ))
            }
        };
        if let Some(s) = file.scale {
            if !(s.is_finite() && s > 0.0) {
                return Err(Error::invalid(
                    what,
                    format!("scale {}: must be positive", number_text(s)),
                ));
            }
        }
        let mut scales = Vec::new();
        for (i, s) in file.scales.iter().enumerate() {
            if !(s.scale.is_finite() && s.scale > 0.0) {
                return Err(Error::invalid(
                    what,
                    format!(
                        "scales[{i}].scale {}: must be positive",
                        number_text(s.scale)
                    ),
                ));
            }
            scales.push((point(&s.at, &format!("scales[{i}].at"))?, s.scale));
        }
        let polylines = |lines: &[Polyline], field: &str| -> Result<Vec<Vec<DVec3>>> {
            lines
                .iter()
                .enumerate()
                .map(|(i, l)| {
                    if l.is_empty() {
                        return Err(Error::invalid(what, format!("{field}[{i}] is empty")));
                    }
                    l.iter()
                        .map(|p| point(p, &format!("{field}[{i}]")))
                        .collect()
                })
                .collect()
        };
        let strokes = polylines(&file.strokes, "strokes")?;
        let inner = match &file.depth {
            Some(d) => polylines(&d.inner, "depth.inner")?,
            None => Vec::new(),
        };
        let regions = |list: &[RegionFile], field: &str| -> Result<Vec<(DVec3, f64)>> {
            list.iter()
                .enumerate()
                .map(|(i, r)| {
                    let center = point(&r.center, &format!("depth.{field}[{i}].center"))?;
                    if !(r.radius.is_finite() && r.radius > 0.0) {
                        return Err(Error::invalid(
                            what,
                            format!(
                                "depth.{field}[{i}].radius {}: must be positive",
                                number_text(r.radius)
                            ),
                        ));
                    }
                    Ok((center, r.radius))
                })
                .collect()
        };
        let (inner_regions, outer_regions) = match &file.depth {
            Some(d) => (
                regions(&d.inner_regions, "inner_regions")?,
                regions(&d.outer_regions, "outer_regions")?,
            ),
            None => (Vec::new(), Vec::new()),
        };
        if kind.uses_strokes() {
            if strokes.is_empty() {
                return Err(Error::invalid(
                    what,
                    format!(
                        "type {} needs \"strokes\" (direction polylines)",
                        kind.name()
                    ),
                ));
            }
            for (i, s) in strokes.iter().enumerate() {
                if s.len() < 2 || s.windows(2).all(|w| (w[1] - w[0]).length() == 0.0) {
                    return Err(Error::invalid(
                        what,
                        format!("strokes[{i}] needs two distinct points to give a direction"),
                    ));
                }
            }
        } else if !strokes.is_empty() {
            return Err(Error::invalid(
                what,
                format!("type {} takes no \"strokes\"", kind.name()),
            ));
        }
        if kind.uses_depth() {
            if inner.is_empty() && inner_regions.is_empty() {
                return Err(Error::invalid(
                    what,
                    format!(
                        "type {} needs \"depth\" with \"inner\" polylines or \"inner_regions\"",
                        kind.name()
                    ),
                ));
            }
        } else if file.depth.is_some() {
            return Err(Error::invalid(
                what,
                format!("type {} takes no \"depth\"", kind.name()),
            ));
        }
        if kind.depth_varying() && (file.scale.is_some() || !scales.is_empty()) {
            return Err(Error::invalid(
                what,
                format!(
                    "type {} takes its scale from the depth field; remove \"scale\"/\"scales\"",
                    kind.name()
                ),
            ));
        }
        Ok(Constraints {
            kind,
            scale: file.scale,
            scales,
            strokes,
            inner,
            inner_regions,
            outer_regions,
        })
    }

    /// Every constraint point must be inside (or on) the model: winding number >= 0.4.
    pub fn check_inside(&self, winding: &Winding, what: &str) -> Result<()> {
        let named = self
            .scales
            .iter()
            .map(|(p, _)| ("scales", *p))
            .chain(self.strokes.iter().flatten().map(|p| ("strokes", *p)))
            .chain(self.inner.iter().flatten().map(|p| ("depth.inner", *p)));
        for (field, p) in named {
            if winding.at(p) < 0.4 {
                return Err(Error::invalid(
                    what,
                    format!(
                        "{field}: point ({}, {}, {}) is outside the mesh",
                        number_text(p.x),
                        number_text(p.y),
                        number_text(p.z)
                    ),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_errors_name_the_problem() {
        let bad = |json: &str, needle: &str| {
            let e = Constraints::parse(json.as_bytes(), "f.json")
                .unwrap_err()
                .to_string();
            assert!(e.contains("f.json") && e.contains(needle), "{e}");
        };
        bad(r#"{"type": "3-c"}"#, "unknown texture type");
        bad(r#"{"scale": 1}"#, "missing field `type`");
        bad(r#"{"type": "0", "colour": 1}"#, "unknown field `colour`");
        bad(r#"{"type": "1-a"}"#, "needs \"strokes\"");
        bad(
            r#"{"type": "1-a", "strokes": [[[0,0,0]]]}"#,
            "two distinct points",
        );
        bad(
            r#"{"type": "2-b", "strokes": [[[0,0,0],[0,0,1]]]}"#,
            "needs \"depth\"",
        );
        bad(r#"{"type": "0", "scale": -1}"#, "must be positive");
        bad(
            r#"{"type": "0", "strokes": [[[0,0,0],[1,0,0]]]}"#,
            "takes no",
        );
        bad(r#"{"type": "#, "not a valid constraints file");
        let ok = Constraints::parse(
            br#"{"type": "2-b", "strokes": [[[0,0,0],[0,0,1]]], "depth": {"inner": [[[0,0,0]]]}}"#,
            "f.json",
        )
        .unwrap();
        assert_eq!(ok.kind, TextureType::TensorLayered);
    }
}
