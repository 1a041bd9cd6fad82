//! `solidsynth.eval`: a volume scored against its exemplar(s), the document `solidsynth eval
//! --json` prints, as a dict.

use crate::detached::run_detached;
use crate::errors::invalid;
use crate::inputs::{exemplar_pair, input_frame, volume_from_array, Picture};
use crate::ints::Int;
use numpy::PyUntypedArray;
use pyo3::prelude::*;
use solidsynth::io::nrrd;
use solidsynth::metrics::{self, EvalParams};
use solidsynth::Volume;
use std::path::PathBuf;

/// The volume argument: an NRRD file, or voxels already in memory.
enum VolumeArg {
    File(PathBuf),
    Voxels(Volume),
}

/// Score `volume` (an NRRD path, or a uint8 array (Z, Y, X) or (Z, Y, X, C)) against
/// `exemplar` (for all three axes, or the x axis with `ey` and `ez`): histograms, patch
/// coherence and completeness, orientations, sharpness and multi-scale measures per axis, the
/// worst axis, the floor (one half of the exemplar against the other) and the ratios. The
/// arguments are `solidsynth eval`'s, with its defaults; the dict is its `--json` document
/// (`schema` 1).
#[pyfunction(name = "eval")]
#[pyo3(signature = (exemplar, volume, *, ey=None, ez=None, frame=None, slices=Int::of(3), seed=Int::of(1)),
       text_signature = "(exemplar, volume, *, ey=None, ez=None, frame=None, slices=3, seed=1)")]
#[allow(clippy::too_many_arguments)]
pub fn evaluate<'py>(
    py: Python<'py>,
    exemplar: &Bound<'py, PyAny>,
    volume: &Bound<'py, PyAny>,
    ey: Option<&Bound<'py, PyAny>>,
    ez: Option<&Bound<'py, PyAny>>,
    frame: Option<String>,
    slices: Int,
    seed: Int,
) -> PyResult<Bound<'py, PyAny>> {
    // `eval --slices`'s range (clap checks it there).
    let slices: u32 = match slices.get::<u32>() {
        Some(n) if (1..=64).contains(&n) => n,
        _ => {
            return Err(invalid(
                format!("--slices {}", slices.text()),
                "must be 1..=64",
            ))
        }
    };
    let seed: u64 = seed.in_range("seed")?;
    let frame = input_frame(frame.as_deref())?;
    let mut exemplars = vec![
        Picture::from_arg(exemplar, "exemplar")?
            .load(py, "exemplar")?
            .0,
    ];
    if let Some((y, z)) = exemplar_pair(ey, ez)? {
        exemplars.push(y.load(py, "--ey")?.0);
        exemplars.push(z.load(py, "--ez")?.0);
    }
    let exemplars =
        metrics::exemplars_in_eval_frame(exemplars, frame).map_err(crate::errors::engine_err)?;
    let volume = match volume.cast::<PyUntypedArray>() {
        Ok(array) => VolumeArg::Voxels(volume_from_array(array, "volume")?),
        Err(_) => VolumeArg::File(volume.extract::<PathBuf>()?),
    };
    let params = EvalParams {
        slices_per_axis: slices,
        seed,
        ..Default::default()
    };
    let document = run_detached(
        py,
        || {},
        move || {
            let (volume, path) = match volume {
                VolumeArg::Voxels(v) => (v, None),
                VolumeArg::File(p) => (nrrd::load(&p)?, Some(p)),
            };
            // Named by its path, as the command line names it.
            let report = metrics::evaluate(&volume, &exemplars, &params).map_err(|e| match e {
                solidsynth::Error::InvalidInput { what, problem } if what == "volume" => {
                    let what = match &path {
                        Some(p) => format!("volume {}", p.display()),
                        None => what,
                    };
                    solidsynth::Error::invalid(what, problem)
                }
                other => other,
            })?;
            let mut document = serde_json::to_value(&report)
                .map_err(|e| solidsynth::Error::Internal(e.to_string()))?;
            document["schema"] = 1.into();
            Ok(document.to_string())
        },
    )?;
    py.import("json")?.call_method1("loads", (document,))
}
