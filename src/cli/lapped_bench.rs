//! `solidsynth bench lapped`: fill time and memory of a lapped model (each run in a fresh
//! process), warm cut latency, and the GPU render time.

use super::output::BenchReport;
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::Command;

#[derive(Args, Debug)]
#[command(next_help_heading = "Benchmark")]
pub struct BenchLappedArgs {
    /// Mesh to fill (a file, or builtin:sphere / builtin:bent-cylinder).
    #[arg(long, default_value = "builtin:sphere")]
    pub mesh: PathBuf,
    /// Tet lattice resolution (builtin:sphere at 10: 6,768 tets).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32)
        .range(crate::lapped::stuffing::MIN_RESOLUTION as i64..=crate::lapped::stuffing::MAX_RESOLUTION as i64))]
    pub resolution: u32,
    /// Solid exemplar (default: `synth --tileable --size 64` of the built-in exemplar).
    #[arg(long)]
    pub exemplar: Option<PathBuf>,
    /// Constraints file.
    #[arg(long)]
    pub field: Option<PathBuf>,
    /// Fill runs (fresh processes); the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub runs: u32,
    /// Cuts of 512x512 through the centre (one process, warm); median and p95 reported.
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=10000))]
    pub cuts: u32,
    /// Also time a 1024x1024 GPU render (`--backend gpu`).
    #[arg(long)]
    pub render: bool,
    /// Print the results as JSON instead of a table.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

/// One measurement of `bench lapped`: the median fill, the warm cuts, the render.
#[derive(serde::Serialize)]
#[serde(tag = "job", rename_all = "lowercase")]
enum LappedRow {
    Fill {
        tets: u64,
        patches: u64,
        total_s: f64,
        mesh_s: f64,
        field_s: f64,
        fill_s: f64,
        peak_rss_mib: f64,
        model_mib: f64,
    },
    Cut {
        size: u32,
        cuts: u32,
        median_ms: f64,
        p95_ms: f64,
        peak_rss_mib: f64,
    },
    Render {
        size: u32,
        render_ms: f64,
        adapter: String,
    },
}

fn child(exe: &Path, args: &[&str]) -> anyhow::Result<serde_json::Value> {
    let mut command = Command::new(exe);
    crate::gpu::context::user_driver_environment(&mut command);
    command.args(args);
    // Named by its subcommand (`lapped fill`): the full line holds this run's temporary paths.
    let job: Vec<&str> = args
        .iter()
        .copied()
        .filter(|a| !a.starts_with('-'))
        .take(2)
        .collect();
    super::bench_child::run_json(&mut command, &job.join(" "))
}

pub fn run(args: BenchLappedArgs) -> anyhow::Result<()> {
    // The inputs are checked before the exemplar is synthesized for them.
    if !args.mesh.to_string_lossy().starts_with("builtin:") {
        crate::mesh::load(&args.mesh)?;
    }
    if let Some(exemplar) = &args.exemplar {
        crate::io::nrrd::load(exemplar)?;
    }
    let dir = tempfile::tempdir()?;
    let exe = std::env::current_exe()?;
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let exemplar = match &args.exemplar {
        Some(p) => p.clone(),
        None => {
            let p = dir.path().join("exemplar.nrrd");
            let out = Command::new(&exe)
                .args(["--quiet", "synth", "--tileable", "--size", "64", "-o"])
                .arg(&p)
                .output()?;
            anyhow::ensure!(out.status.success(), "synth of the exemplar failed");
            p
        }
    };
    let model = dir.path().join("bench.lst");
    let mut fill_args = vec![
        "--quiet".to_string(),
        "lapped".into(),
        "fill".into(),
        "--mesh".into(),
        s(&args.mesh),
        "--exemplar".into(),
        s(&exemplar),
        "--resolution".into(),
        args.resolution.to_string(),
        "--json".into(),
        "-o".into(),
        s(&model),
    ];
    if let Some(f) = &args.field {
        fill_args.push("--field".into());
        fill_args.push(s(f));
    }
    let fill_refs: Vec<&str> = fill_args.iter().map(String::as_str).collect();
    let mut runs = Vec::new();
    for _ in 0..args.runs.max(1) {
        runs.push(child(&exe, &fill_refs)?);
    }
    let total = |v: &serde_json::Value| v["total_seconds"].as_f64().unwrap_or(f64::NAN);
    runs.sort_by(|a, b| total(a).total_cmp(&total(b)));
    let m = &runs[runs.len() / 2];
    let f = |k: &str| m[k].as_f64().unwrap_or(f64::NAN);
    let mib = |bytes: f64| bytes / (1 << 20) as f64;
    let mut report = BenchReport::new(
        "lapped",
        args.json,
        serde_json::json!({"mesh": args.mesh, "resolution": args.resolution,
            "exemplar": args.exemplar, "field": args.field, "runs": args.runs,
            "cuts": args.cuts, "render": args.render}),
    );
    report.line(format!(
        "lapped fill of {} at resolution {}: median of {} run(s)",
        args.mesh.display(),
        args.resolution,
        runs.len()
    ));
    report.line(format!(
        "  {} tets ({} vertices, dihedral {:.1}..{:.1} deg, {} inverted), {} patches, {:.1} \
         layers/tet",
        m["tets"],
        m["vertices"],
        f("min_dihedral_degrees"),
        f("max_dihedral_degrees"),
        m["inverted_tets"],
        m["patches"],
        f("mean_layers_per_tet")
    ));
    let fill = LappedRow::Fill {
        tets: m["tets"].as_u64().unwrap_or(0),
        patches: m["patches"].as_u64().unwrap_or(0),
        total_s: f("total_seconds"),
        mesh_s: f("mesh_seconds"),
        field_s: f("field_seconds"),
        fill_s: f("fill_seconds"),
        peak_rss_mib: mib(f("peak_rss_bytes")),
        model_mib: mib(f("model_bytes")),
    };
    report.row(
        fill,
        format!(
            "  total {:.3} s = mesh {:.3} s + field {:.3} s + fill {:.3} s; peak RSS {:.1} MiB; \
             model {:.1} MiB",
            f("total_seconds"),
            f("mesh_seconds"),
            f("field_seconds"),
            f("fill_seconds"),
            mib(f("peak_rss_bytes")),
            mib(f("model_bytes"))
        ),
    );
    // The cut through the model's centre, warm: one cold cut first, which `lapped cut` leaves
    // out of its median and p95, then `cuts` measured ones.
    let v = child(
        &exe,
        &[
            "--quiet",
            "lapped",
            "cut",
            &s(&model),
            "--origin",
            "0,0,0",
            "--normal",
            "0.3,0.2,1",
            "--size",
            "512",
            "--repeat",
            &(args.cuts.max(1) + 1).to_string(),
            "--json",
            "-o",
            &s(&dir.path().join("cut.png")),
        ],
    )?;
    let number = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let cut = LappedRow::Cut {
        size: 512,
        cuts: args.cuts.max(1),
        median_ms: number(&v, "median_ms"),
        p95_ms: number(&v, "p95_ms"),
        peak_rss_mib: mib(number(&v, "peak_rss_bytes")),
    };
    report.row(
        cut,
        format!(
            "  cut 512x512 ({} pixels inside): median {:.2} ms, p95 {:.2} ms over {} cuts; peak \
             RSS {:.1} MiB",
            v["pixels_inside"],
            number(&v, "median_ms"),
            number(&v, "p95_ms"),
            args.cuts.max(1),
            mib(number(&v, "peak_rss_bytes"))
        ),
    );
    if args.render {
        let v = child(
            &exe,
            &[
                "--quiet",
                "lapped",
                "render",
                &s(&model),
                "--size",
                "1024",
                "--backend",
                "gpu",
                "--json",
                "-o",
                &s(&dir.path().join("view.png")),
            ],
        )?;
        let adapter = v["adapter"].as_str().unwrap_or("?").to_string();
        let text = format!(
            "  render 1024x1024: {:.1} ms on {adapter}",
            number(&v, "render_ms")
        );
        let render = LappedRow::Render {
            size: 1024,
            render_ms: number(&v, "render_ms"),
            adapter,
        };
        report.row(render, text);
    }
    report.finish();
    Ok(())
}
