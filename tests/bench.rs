//! `bench compare`: the same jobs on the CPU backend and on every Vulkan adapter, with the
//! same-bytes check (CI has lavapipe, so the check runs there on a GPU backend).

use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_solidsynth"))
        .env("SOLIDSYNTH_LOG", "warn")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn compare_runs_every_job_on_every_device_with_the_cpu_bytes() {
    let out = run(&["bench", "compare", "--quick", "--runs", "1", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let devices = doc["devices"].as_array().unwrap();
    assert_eq!(devices[0]["kind"], "cpu", "{doc}");
    let adapters = solidsynth::device::list_adapters();
    if std::env::var_os("CI").is_some() {
        // CI installs lavapipe: a GPU backend must be in the table, labelled as software.
        assert!(devices.iter().any(|d| d["kind"] == "software GPU"), "{doc}");
    }
    let names: std::collections::BTreeSet<&str> =
        adapters.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(devices.len(), 1 + names.len(), "{doc}");

    let jobs = doc["jobs"].as_array().unwrap();
    assert_eq!(jobs.len(), 6, "{doc}");
    for job in jobs {
        let cells = job["cells"].as_array().unwrap();
        assert_eq!(cells.len(), devices.len(), "{job}");
        for cell in cells {
            let median = cell["median"].as_f64().unwrap();
            assert!(median > 0.0 && median.is_finite(), "{job}");
            assert_eq!(cell["same_bytes_as_cpu"], true, "{job}");
            if job["unit"] == "ms" {
                assert!(cell["p95"].as_f64().unwrap() >= median, "{job}");
            }
        }
    }
}

#[test]
fn compare_prints_markdown_and_refuses_an_unknown_adapter() {
    let out = run(&[
        "bench",
        "compare",
        "--quick",
        "--runs",
        "1",
        "--adapters",
        "none",
    ]);
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(table.contains("| job | CPU | same bytes |"), "{table}");
    assert_eq!(
        table.lines().filter(|l| l.starts_with("| ")).count(),
        7,
        "{table}"
    );

    for adapters in ["no-such-card", "none,no-such-card", " "] {
        let out = run(&["bench", "compare", "--adapters", adapters]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{adapters}: {err}");
        assert!(err.contains("--adapters"), "{adapters}: {err}");
    }

    // An exemplar synth refuses is the user's input: exit 2, naming the file.
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.png");
    let out = run(&[
        "bench",
        "compare",
        "--quick",
        "--adapters",
        "none",
        missing.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("missing.png"), "{err}");
}

#[test]
fn a_benchmark_whose_run_refuses_the_users_values_exits_2_in_its_words() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.png");
    std::fs::write(&bad, b"not an image").unwrap();
    let out = run(&[
        "bench",
        "gradient-synth",
        bad.to_str().unwrap(),
        "--sizes",
        "16",
        "--runs",
        "1",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    // The run that refused, then its own message.
    assert!(
        err.contains("error: gradient synth --size 16 --backend cpu: invalid exemplar"),
        "{err}"
    );
    assert!(err.contains("bad.png: cannot decode image"), "{err}");
}
