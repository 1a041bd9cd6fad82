//! A solid's synthesis settings as the command line's flags give them, checked with its
//! messages.

use crate::errors::engine_err;
use crate::inputs::{backend_choice, candidate_mode, color_source, PassesArg};
use crate::ints::Int;
use pyo3::prelude::*;
use solidsynth::solid::limits;
use solidsynth::{BackendChoice, GpuOptions, SynthOptions, SynthParams};

/// A solid's synthesis settings as given: what `Solid.options` reports and `Solid.load` takes
/// (the analysis settings live in the analysis, and so in its `.ssa` file).
#[derive(Clone)]
pub struct SynthSettings {
    pub params: SynthParams,
    pub max_group: Option<u32>,
    pub backend: String,
    pub choice: BackendChoice,
    pub adapter: Option<String>,
}

impl SynthSettings {
    #[allow(clippy::too_many_arguments)]
    pub fn parse(
        seed: Int,
        jitter: f32,
        backend: String,
        adapter: Option<String>,
        candidates: &str,
        passes: &PassesArg,
        color: &str,
        coarse_cache: Option<Int>,
        max_group: Option<Int>,
    ) -> PyResult<SynthSettings> {
        let choice = backend_choice(&backend)?;
        let seed: u64 = seed.in_range("seed")?;
        // Values past u32 get the engine's own message for a size it refuses (its real range).
        let cache_refused = || {
            SynthParams {
                coarse_cache: Some(0),
                ..SynthParams::default()
            }
            .validate()
            .unwrap_err()
        };
        let coarse_cache: Option<u32> = coarse_cache
            .map(|c| c.or_refused(cache_refused()))
            .transpose()?;
        let max_group: Option<u32> = max_group
            .map(|g| g.or_refused(limits::check_max_group(0).unwrap_err()))
            .transpose()?;
        if let Some(side) = max_group {
            limits::check_max_group(side).map_err(engine_err)?;
        }
        let params = SynthParams {
            seed,
            jitter,
            candidates: candidate_mode(candidates)?,
            passes: passes.schedule()?,
            color: color_source(color)?,
            coarse_cache,
        };
        params.validate().map_err(engine_err)?;
        Ok(SynthSettings {
            params,
            max_group,
            backend,
            choice,
            adapter,
        })
    }

    /// The GPU options as the command line makes them: the environment's, `adapter` first.
    pub fn gpu_options(&self) -> GpuOptions {
        let mut options = GpuOptions::from_env();
        if self.adapter.is_some() {
            options.adapter_filter = self.adapter.clone();
        }
        options
    }

    /// The engine's options as the command line gives them (its defaults but `--max-group`).
    pub fn synth_options(&self) -> SynthOptions {
        SynthOptions {
            max_group: self.max_group,
            ..Default::default()
        }
    }
}
