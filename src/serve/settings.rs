//! The page's parameters of a new solid (`POST /api/solids?...`), validated as the command line
//! validates its flags, over the server's own settings.

use super::api::{from_error, Query};
use super::jobs::SolidSettings;
use crate::lazy::{ColorSource, PassSchedule, SynthParams};
use crate::solid::FeatureMasks;

/// The parameters `POST /api/solids` takes besides the exemplar.
pub const SOLID_PARAMETERS: &[&str] = &[
    "seed",
    "jitter",
    "color",
    "passes",
    "feature",
    "coarse_cache",
];

/// `seed`, `jitter` (0..=8, as the command line), `color` (`average`, `fitted`, `matched`, `x`, `y`, `z`), `passes` (`N` or
/// `N0,N1,N2,N3`), `feature` (`auto`, `edges`, `none`) and `coarse_cache` (0: none, else a
/// multiple of 64), each defaulting to the server's.
pub fn solid_settings(server: &SynthParams, q: &Query) -> Result<SolidSettings, (u16, String)> {
    let invalid =
        |key: &str, value: &str, why: String| (400, format!("invalid {key} {value:?}: {why}"));
    let mut params = SynthParams {
        seed: q.u64_in("seed", 0, u32::MAX as u64)?.unwrap_or(0),
        ..server.clone()
    };
    if let Some(j) = q.f64_in("jitter", 0.0, crate::contract::jitter::MAX_JITTER as f64)? {
        params.jitter = j as f32;
    }
    if let Some(text) = q.get("color") {
        let color: ColorSource = text.parse().map_err(|e| invalid("color", text, e))?;
        if let ColorSource::PerChannel(_) = color {
            return Err(invalid(
                "color",
                text,
                "one source for the whole solid (average, fitted, matched, x, y or z)".into(),
            ));
        }
        params.color = color;
    }
    if let Some(text) = q.get("passes") {
        let passes: PassSchedule = text.parse().map_err(|e| invalid("passes", text, e))?;
        params.passes = passes;
    }
    if let Some(period) = q.u64_in("coarse_cache", 0, 4096)? {
        params.coarse_cache = (period > 0).then_some(period as u32);
    }
    params.validate().map_err(from_error)?;
    let feature_masks = match q.get("feature") {
        None | Some("auto") => FeatureMasks::Auto,
        Some("edges") => FeatureMasks::Edges,
        Some("none") => FeatureMasks::None,
        Some(other) => {
            return Err(invalid(
                "feature",
                other,
                "must be auto, edges or none".into(),
            ));
        }
    };
    Ok(SolidSettings {
        params,
        feature_masks,
    })
}
