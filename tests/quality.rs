//! Quality regression: evaluation scores of the repository's fixtures, recorded in
//! `tests/fixtures/scores.json`: the floors (exact: they only depend on the metrics) and the
//! worst-axis ratios of small synthesized volumes (bounds: a synthesis change may improve them
//! freely but not worsen any by more than 10%). Re-record deliberately with
//! `SOLIDSYNTH_RECORD_SCORES=1 cargo test --test quality` and explain the change in the commit.

mod common;

use solidsynth::metrics::{score_images, slices::halves, EvalParams};
use std::collections::BTreeMap;

const FIXTURES: &[&str] = &[
    "cells32.png",
    "marble32.png",
    "stripes32.png",
    "cc0_brick64.png",
    "cc0_gravel64.png",
];

fn scores_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/scores.json")
}

/// How a fixture is analysed in [`synthesized`].
#[derive(Clone, Copy, PartialEq)]
enum Setup {
    /// One shared exemplar (the cyclic frame), no feature channel: "synth/".
    Plain,
    /// The same with the automatic feature channel: "synth-auto/".
    Auto,
    /// What the CLI does by default for a square image: the paper's frame (three exemplars,
    /// Ey transposed) with the automatic feature channel, scored in that frame: "synth-paper/".
    Paper,
}

/// Worst-axis ratios of a 24^3 synthesis of each synthesizable fixture (CPU backend, seed 1)
/// for each [`Setup`].
fn synthesized() -> BTreeMap<String, serde_json::Value> {
    use solidsynth::analysis::frame::{to_crate_frame, InputFrame};
    use solidsynth::analysis::{AnalysisInput, AnalysisParams};
    use solidsynth::exemplar::{feature, Border};
    use solidsynth::lazy::{Box3, SynthParams, Synthesizer};
    let names = [
        "cells32.png",
        "marble32.png",
        "cc0_gravel64.png",
        "cc0_brick64.png",
    ];
    let runs = names
        .iter()
        .flat_map(|n| [(*n, Setup::Plain), (*n, Setup::Auto), (*n, Setup::Paper)]);
    runs.map(|(name, setup)| {
        let ex = common::fixture(name);
        let exemplars = match setup {
            Setup::Paper => to_crate_frame(vec![ex.clone()], InputFrame::Paper),
            _ => vec![ex.clone()],
        };
        // Masks as the CLI makes them: of the given image, then into the frame.
        let masks = match setup {
            Setup::Plain => vec![],
            Setup::Auto => feature::auto_masks(std::slice::from_ref(&ex)),
            Setup::Paper => to_crate_frame(
                feature::auto_masks(std::slice::from_ref(&ex)),
                InputFrame::Paper,
            ),
        };
        let auto = setup != Setup::Plain;
        let input = AnalysisInput {
            masks,
            names: exemplars.iter().map(|_| name.to_string()).collect(),
            exemplars: exemplars.clone(),
            border: Border::Wrap,
        };
        let a = solidsynth::lazy::analyze(
            &input,
            &AnalysisParams::default(),
            &solidsynth::backend::Compute::Cpu,
            &|_, _| {},
        )
        .unwrap();
        assert_eq!(a.has_feature, auto, "{name}");
        let params = SynthParams {
            seed: 1,
            ..Default::default()
        };
        let mut s = Synthesizer::new(&a, params, &solidsynth::backend::Compute::Cpu).unwrap();
        let v = s
            .synthesize(Box3::new([0; 3], [24; 3]), &|_, _| {})
            .unwrap();
        let r = solidsynth::metrics::evaluate(&v, &exemplars, &EvalParams::default()).unwrap();
        let prefix = match setup {
            Setup::Plain => "synth",
            Setup::Auto => "synth-auto",
            Setup::Paper => "synth-paper",
        };
        (
            format!("{prefix}/{name}"),
            serde_json::to_value(r.worst_ratio).unwrap(),
        )
    })
    .collect()
}

#[test]
fn synthesized_fixture_scores_stay_within_recorded_bounds() {
    let now = synthesized();
    if std::env::var_os("SOLIDSYNTH_RECORD_SCORES").is_some() {
        record(now);
        return;
    }
    let recorded = recorded();
    for (key, value) in &now {
        let want = recorded
            .get(key)
            .unwrap_or_else(|| panic!("{key} not recorded"));
        for (measure, v) in value.as_object().unwrap() {
            let (got, bound) = (v.as_f64().unwrap(), want[measure].as_f64().unwrap());
            assert!(
                got <= bound * 1.10 + 0.05,
                "{key} {measure}: {got:.3} worse than recorded {bound:.3}"
            );
        }
    }
}

fn recorded() -> BTreeMap<String, serde_json::Value> {
    serde_json::from_str(&std::fs::read_to_string(scores_path()).unwrap()).unwrap()
}

/// Merge `entries` into the recorded file (one test at a time: both tests record).
fn record(entries: BTreeMap<String, serde_json::Value>) {
    static FILE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = FILE.lock().unwrap_or_else(|e| e.into_inner());
    let mut all = std::fs::read_to_string(scores_path())
        .ok()
        .and_then(|s| serde_json::from_str::<BTreeMap<String, serde_json::Value>>(&s).ok())
        .unwrap_or_default();
    all.extend(entries);
    std::fs::write(
        scores_path(),
        serde_json::to_string_pretty(&all).unwrap() + "\n",
    )
    .unwrap();
}

/// The floor (one half of the exemplar against the other) of every fixture.
fn floors() -> BTreeMap<String, serde_json::Value> {
    FIXTURES
        .iter()
        .map(|name| {
            let ex = common::fixture(name);
            let (a, b) = halves(&ex);
            let s = score_images(&[b], &a, &EvalParams::default(), 100);
            (format!("floor/{name}"), serde_json::to_value(s).unwrap())
        })
        .collect()
}

#[test]
fn fixture_scores_match_the_recorded_ones() {
    let now = floors();
    if std::env::var_os("SOLIDSYNTH_RECORD_SCORES").is_some() {
        record(now);
        return;
    }
    let recorded: BTreeMap<String, serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(scores_path()).unwrap()).unwrap();
    for (key, value) in &now {
        let want = recorded
            .get(key)
            .unwrap_or_else(|| panic!("{key} not recorded"));
        for (measure, v) in value.as_object().unwrap() {
            let (got, want) = (v.as_f64().unwrap(), want[measure].as_f64().unwrap());
            assert!(
                (got - want).abs() <= 1e-9 * want.abs().max(1.0),
                "{key} {measure}: {got} vs recorded {want}"
            );
        }
    }
}
