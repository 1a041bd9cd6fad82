//! Quality regression: evaluation scores of the repository's fixtures, recorded in
//! `tests/fixtures/scores.json`. A change to the metrics (or, once synthesis exists, to synthesis)
//! that moves a score outside its recorded bound fails here. Re-record deliberately with
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
        std::fs::write(
            scores_path(),
            serde_json::to_string_pretty(&now).unwrap() + "\n",
        )
        .unwrap();
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
