//! `solidsynth bench compare`: the same jobs on the CPU backend and on every GPU adapter present
//! (software devices such as lavapipe included and labelled), as one Markdown table with ratio
//! columns and a check that every device wrote the CPU backend's bytes.
//!
//! Every measurement runs in a child `solidsynth` process, exactly as a user would run the job:
//! volumes and surfaces in fresh processes (median of the runs' synthesis times, analysis
//! excluded through a warm cache), cuts through one warm session each (`cut --repeat`).

use super::bench_child::{run_json, ChildRefused};
use super::output;
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::Command;

#[derive(Args, Debug)]
#[command(next_help_heading = "Benchmark")]
pub struct BenchCompareArgs {
    /// Exemplar image or .ssa (default: the built-in exemplar).
    pub input: Option<PathBuf>,
    /// Smaller jobs and fewer runs: a 64^3 volume, 128^2 cuts, the bunny at 128, 3 runs.
    #[arg(long)]
    pub quick: bool,
    /// Runs per job and device: fresh processes for volumes and surfaces, warm repeats for cuts
    /// (twice as many, since one cut is short). Default 5, or 3 with --quick.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub runs: Option<u32>,
    /// Only the GPU adapters whose names contain one of these (case-insensitive),
    /// comma-separated; `none` measures the CPU backend alone. Default: every adapter.
    #[arg(long, value_delimiter = ',', value_name = "NAME,...")]
    pub adapters: Vec<String>,
    /// Print the results as JSON instead of Markdown.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

/// Where a job runs: the CPU backend or one GPU adapter.
#[derive(Clone, Debug, serde::Serialize)]
struct Device {
    /// The column's name: `CPU`, or the adapter's name.
    label: String,
    /// `cpu`, or `gpu`, `software GPU` (a Vulkan device that runs on the host's cores, e.g.
    /// lavapipe: a correctness device, not a performance target), `integrated GPU`.
    kind: String,
    /// The adapter's driver and driver version; the CPU's model and thread count for `cpu`.
    details: String,
    /// The arguments that select it in a child process.
    #[serde(skip)]
    args: Vec<String>,
}

/// One job of the table.
#[derive(Clone, Debug)]
struct Job {
    /// The row's name, with the unit of its numbers.
    title: String,
    /// The `solidsynth` subcommand and its arguments, before the device's and the output's.
    args: Vec<String>,
    /// Output file name in the scratch folder (its extension picks the format).
    output: &'static str,
    measure: Measure,
}

#[derive(Clone, Copy, Debug)]
enum Measure {
    /// `synthesis_seconds` of `--json`, a fresh process per run.
    FreshSeconds,
    /// `median_ms` and `p95_ms` of `cut --repeat K --json` in one process.
    WarmCut,
}

/// One job on one device.
#[derive(Clone, Debug, serde::Serialize)]
struct Cell {
    device: String,
    /// Seconds for fresh-process jobs, milliseconds for cuts.
    median: f64,
    /// Cuts only: the 95th percentile of the warm repeats.
    p95: Option<f64>,
    /// Every run's time (fresh-process jobs).
    samples: Vec<f64>,
    /// Whether the output's bytes equal the CPU backend's (always true for the CPU column;
    /// false when the job failed).
    same_bytes_as_cpu: bool,
    /// Why the job failed on this device (the table says `failed`; the others still run).
    error: Option<String>,
}

#[derive(serde::Serialize)]
struct JobResult {
    job: String,
    unit: &'static str,
    cells: Vec<Cell>,
}

pub fn run(args: BenchCompareArgs) -> anyhow::Result<()> {
    let runs = args.runs.unwrap_or(if args.quick { 3 } else { 5 });
    let devices = devices(&args.adapters)?;
    let scratch = tempfile::tempdir()?;
    let bunny = scratch.path().join("bunny.obj");
    std::fs::write(&bunny, crate::mesh::BUNNY_OBJ)?;
    let jobs = jobs(args.quick, runs, &bunny);
    let exe = std::env::current_exe()?;
    let cache = scratch.path().join("cache");
    let child = |job_args: &[String], device: &Device, output: &Path| {
        let mut cmd = Command::new(&exe);
        crate::gpu::context::user_driver_environment(&mut cmd);
        cmd.env("SOLIDSYNTH_CACHE_DIR", &cache)
            .args(["--quiet"])
            .args(job_args)
            .args(&device.args)
            .arg("--json")
            .arg("-o")
            .arg(output);
        if let Some(input) = &args.input {
            cmd.arg("--").arg(input);
        }
        let summary = run_json(&mut cmd, &job_args.join(" "))?;
        // The column's device, not another whose name contains its label.
        let backend = summary["backend"].as_str().unwrap_or_default();
        if !backend.starts_with(&device.backend_prefix()) {
            anyhow::bail!("ran on {backend}, not on {}", device.label);
        }
        Ok(summary)
    };
    // Analyse once, on the CPU, so every job and device reads the same cached analysis.
    let warm_up = ["synth", "--size", "16"].map(String::from);
    child(&warm_up, &devices[0], &scratch.path().join("warm.nrrd")).map_err(|e| {
        // `synth` refused INPUT: the user's input (exit 2), in `synth`'s words.
        match e.downcast::<ChildRefused>() {
            Ok(refused) => anyhow::Error::new(crate::Error::invalid("INPUT", refused.message)),
            Err(e) => e,
        }
    })?;

    let mut results = Vec::new();
    for job in &jobs {
        let mut cells: Vec<Cell> = Vec::new();
        // The CPU backend's output (device 0), read once: what every other device must equal.
        let mut cpu_bytes: Option<Vec<u8>> = None;
        for (d, device) in devices.iter().enumerate() {
            tracing::info!("bench compare: {} on {}", job.title, device.label);
            let output = scratch.path().join(format!("device{d}-{}", job.output));
            let measured = measure(job, runs, || child(&job.args, device, &output));
            let cell = match measured {
                Ok((median, p95, samples)) => {
                    let bytes = std::fs::read(&output)?;
                    let same_bytes_as_cpu = match &cpu_bytes {
                        Some(cpu) => *cpu == bytes,
                        // The CPU column itself, or a job the CPU backend failed.
                        None => d == 0,
                    };
                    if d == 0 {
                        cpu_bytes = Some(bytes);
                    }
                    Cell {
                        device: device.label.clone(),
                        median,
                        p95,
                        samples,
                        same_bytes_as_cpu,
                        error: None,
                    }
                }
                Err(e) => {
                    tracing::warn!("bench compare: {} on {}: {e:#}", job.title, device.label);
                    Cell {
                        device: device.label.clone(),
                        median: f64::NAN,
                        p95: None,
                        samples: Vec::new(),
                        same_bytes_as_cpu: false,
                        error: Some(format!("{e:#}")),
                    }
                }
            };
            cells.push(cell);
        }
        results.push(JobResult {
            job: job.title.clone(),
            unit: match job.measure {
                Measure::FreshSeconds => "s",
                Measure::WarmCut => "ms",
            },
            cells,
        });
    }

    if args.json {
        let doc = serde_json::json!({
            "schema": super::output::SUMMARY_SCHEMA,
            "bench": "compare",
            "version": env!("CARGO_PKG_VERSION"),
            "input": args.input,
            "quick": args.quick,
            "runs": runs,
            "devices": devices,
            "jobs": results,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print!("{}", markdown(&devices, &results, runs));
    }
    let failed = results
        .iter()
        .flat_map(|r| &r.cells)
        .filter(|c| c.error.is_some())
        .count();
    if failed > 0 {
        anyhow::bail!("{failed} job(s) failed on a device (see the table and the warnings)");
    }
    if results
        .iter()
        .any(|r| r.cells.iter().any(|c| !c.same_bytes_as_cpu))
    {
        anyhow::bail!("a device wrote bytes that differ from the CPU backend's (see the table)");
    }
    Ok(())
}

/// Run `job` `runs` times through `child` (once for a cut, which repeats inside): the median,
/// the cuts' p95, and the fresh runs' samples.
fn measure(
    job: &Job,
    runs: u32,
    child: impl Fn() -> anyhow::Result<serde_json::Value>,
) -> anyhow::Result<(f64, Option<f64>, Vec<f64>)> {
    match job.measure {
        Measure::FreshSeconds => {
            let mut samples = Vec::new();
            for _ in 0..runs {
                samples.push(number(&child()?, "synthesis_seconds", &job.title)?);
            }
            Ok((output::median(&samples), None, samples))
        }
        Measure::WarmCut => {
            let summary = child()?;
            Ok((
                number(&summary, "median_ms", &job.title)?,
                Some(number(&summary, "p95_ms", &job.title)?),
                Vec::new(),
            ))
        }
    }
}

/// The CPU backend first, then each GPU adapter that `filters` admits (all when empty).
fn devices(filters: &[String]) -> anyhow::Result<Vec<Device>> {
    let mut devices = vec![Device {
        label: "CPU".into(),
        kind: "cpu".into(),
        details: format!(
            "{}, {} threads",
            cpu_model(),
            std::thread::available_parallelism().map_or(1, |n| n.get())
        ),
        args: ["--backend", "cpu"].map(String::from).to_vec(),
    }];
    let filters: Vec<String> = filters.iter().map(|f| f.trim().to_lowercase()).collect();
    if filters == ["none"] {
        return Ok(devices);
    }
    let adapters = crate::gpu::context::list_adapters();
    let available: Vec<&str> = adapters.iter().map(|a| a.name.as_str()).collect();
    for f in &filters {
        if f.is_empty() || f == "none" || !available.iter().any(|n| n.to_lowercase().contains(f)) {
            anyhow::bail!(crate::Error::invalid(
                format!("--adapters {}", filters.join(",")),
                if f.is_empty() || f == "none" {
                    "`none` stands alone, and no name may be empty".to_string()
                } else {
                    format!(
                        "no Vulkan adapter's name contains {f:?} (adapters: {})",
                        if available.is_empty() {
                            "none".to_string()
                        } else {
                            available.join(", ")
                        }
                    )
                },
            ));
        }
    }
    let mut seen = std::collections::BTreeSet::new();
    for info in adapters {
        let name = info.name.clone();
        let wanted = filters.is_empty()
            || filters
                .iter()
                .any(|f| name.to_lowercase().contains(f.as_str()));
        // `--adapter` selects by name, so identical adapters (two cards of one model) are one
        // column: the first of them.
        if !wanted || !seen.insert(name.clone()) {
            continue;
        }
        let kind = match info.device_type {
            wgpu::DeviceType::Cpu => "software GPU",
            wgpu::DeviceType::IntegratedGpu => "integrated GPU",
            wgpu::DeviceType::VirtualGpu => "virtual GPU",
            _ => "gpu",
        };
        devices.push(Device {
            label: name.clone(),
            kind: kind.into(),
            details: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
            args: vec!["--backend".into(), "gpu".into(), "--adapter".into(), name],
        });
    }
    if devices.len() == 1 {
        tracing::warn!("bench compare: no Vulkan adapter found; the CPU backend alone");
    }
    Ok(devices)
}

impl Device {
    /// How a child's `--json` summary names this device's backend (`Compute::describe`).
    fn backend_prefix(&self) -> String {
        if self.kind == "cpu" {
            "cpu (".into()
        } else {
            format!("gpu {} (", self.label)
        }
    }
}

/// The jobs of the table: a volume, warm cuts (axis-aligned and oblique, with the default
/// passes and with the fast flags), and a surface bake of the bunny.
fn jobs(quick: bool, runs: u32, bunny: &Path) -> Vec<Job> {
    let (volume, cut, surface) = if quick {
        (64, 128, 128)
    } else {
        (128, 256, 512)
    };
    let strings = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let fast = ["--coarse-cache", "128", "--passes", "2,2,2,1"];
    // One more than measured: the first cut of a session is cold and left out of its statistics.
    let repeat = (2 * runs + 1).to_string();
    let cut_job = |title: String, normal: &str, extra: &[&str], output| Job {
        title,
        args: [
            strings(&["cut", "--origin", "0,0,32", "--normal", normal]),
            strings(&["--size", &cut.to_string(), "--repeat", &repeat]),
            strings(extra),
        ]
        .concat(),
        output,
        measure: Measure::WarmCut,
    };
    let mut bunny_args = strings(&["surface", "--resolution", &surface.to_string(), "--mesh"]);
    bunny_args.push(bunny.display().to_string());
    vec![
        Job {
            title: format!("synth --size {volume} (s)"),
            args: strings(&["synth", "--size", &volume.to_string()]),
            output: "volume.nrrd",
            measure: Measure::FreshSeconds,
        },
        cut_job(format!("warm z cut {cut}^2 (ms)"), "0,0,1", &[], "z.png"),
        cut_job(
            format!("warm oblique cut {cut}^2 (ms)"),
            "1,2,3",
            &[],
            "oblique.png",
        ),
        cut_job(
            format!("warm z cut {cut}^2, fast flags (ms)"),
            "0,0,1",
            &fast,
            "z-fast.png",
        ),
        cut_job(
            format!("warm oblique cut {cut}^2, fast flags (ms)"),
            "1,2,3",
            &fast,
            "oblique-fast.png",
        ),
        Job {
            title: format!("surface, bunny at {surface} (s)"),
            args: bunny_args,
            output: "bunny.glb",
            measure: Measure::FreshSeconds,
        },
    ]
}

/// The table: a row per job, a column per device, then each GPU's speed-up over the CPU backend
/// (the CPU's median divided by the device's) and whether every device wrote the CPU's bytes.
fn markdown(devices: &[Device], results: &[JobResult], runs: u32) -> String {
    let mut out = String::new();
    out.push_str(&format!(
        "solidsynth {} `bench compare`: medians of {runs} fresh runs (volumes, surfaces; \
         analysis excluded) or of {} warm repeats (cuts, with the 95th percentile in brackets).\n\n",
        env!("CARGO_PKG_VERSION"),
        2 * runs
    ));
    for d in devices {
        out.push_str(&format!("- **{}** ({}): {}\n", d.label, d.kind, d.details));
    }
    if devices.len() == 1 {
        out.push_str("- no GPU adapter measured\n");
    }
    out.push('\n');
    let mut header = vec!["job".to_string()];
    header.extend(devices.iter().map(|d| d.label.clone()));
    header.extend(devices[1..].iter().map(|d| format!("CPU / {}", d.label)));
    header.push("same bytes".into());
    out.push_str(&format!("| {} |\n", header.join(" | ")));
    out.push_str(&format!("|{}\n", "---|".repeat(header.len())));
    for r in results {
        let mut row = vec![r.job.clone()];
        row.extend(r.cells.iter().map(|c| match (&c.error, c.p95) {
            (Some(_), _) => "failed".to_string(),
            (None, Some(p95)) => format!("{} ({})", figure(c.median), figure(p95)),
            (None, None) => figure(c.median),
        }));
        let cpu = r.cells[0].median;
        row.extend(r.cells[1..].iter().map(|c| {
            let ratio = cpu / c.median;
            if ratio.is_finite() {
                format!("{ratio:.2}")
            } else {
                "-".into()
            }
        }));
        let differing: Vec<&str> = r
            .cells
            .iter()
            .filter(|c| !c.same_bytes_as_cpu && c.error.is_none())
            .map(|c| c.device.as_str())
            .collect();
        let compared = r.cells.iter().filter(|c| c.error.is_none()).count();
        row.push(if r.cells[0].error.is_some() {
            "-".into()
        } else if !differing.is_empty() {
            format!("**no**: {}", differing.join(", "))
        } else if compared < 2 && r.cells.len() > 1 {
            "-".into()
        } else {
            "yes".into()
        });
        out.push_str(&format!("| {} |\n", row.join(" | ")));
    }
    out
}

/// Three significant figures, without exponents.
fn figure(x: f64) -> String {
    let decimals = if x >= 100.0 {
        0
    } else if x >= 10.0 {
        1
    } else if x >= 1.0 {
        2
    } else {
        3
    };
    format!("{x:.decimals$}")
}

fn number(summary: &serde_json::Value, key: &str, job: &str) -> anyhow::Result<f64> {
    summary[key]
        .as_f64()
        .ok_or_else(|| anyhow::anyhow!("{job}: the child's --json summary has no {key}"))
}

/// The CPU's model name (Linux's /proc/cpuinfo), or the architecture elsewhere.
fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn device(label: &str, kind: &str) -> Device {
        Device {
            label: label.into(),
            kind: kind.into(),
            details: "details".into(),
            args: Vec::new(),
        }
    }

    fn cell(device: &str, median: f64, same: bool, error: Option<&str>) -> Cell {
        Cell {
            device: device.into(),
            median,
            p95: None,
            samples: vec![median],
            same_bytes_as_cpu: same,
            error: error.map(String::from),
        }
    }

    #[test]
    fn the_table_gives_ratios_mismatches_and_failures() {
        let devices = [
            device("CPU", "cpu"),
            device("A", "gpu"),
            device("B", "software GPU"),
        ];
        let results = [
            JobResult {
                job: "fine (s)".into(),
                unit: "s",
                cells: vec![
                    cell("CPU", 2.0, true, None),
                    cell("A", 0.5, true, None),
                    cell("B", 4.0, true, None),
                ],
            },
            JobResult {
                job: "mismatch (s)".into(),
                unit: "s",
                cells: vec![
                    cell("CPU", 1.0, true, None),
                    cell("A", 1.0, false, None),
                    cell("B", f64::NAN, false, Some("out of memory")),
                ],
            },
        ];
        let table = markdown(&devices, &results, 3);
        assert!(
            table.contains("| job | CPU | A | B | CPU / A | CPU / B | same bytes |"),
            "{table}"
        );
        assert!(
            table.contains("| fine (s) | 2.00 | 0.500 | 4.00 | 4.00 | 0.50 | yes |"),
            "{table}"
        );
        assert!(
            table.contains("| mismatch (s) | 1.00 | 1.00 | failed | 1.00 | - | **no**: A |"),
            "{table}"
        );
        assert!(table.contains("- **B** (software GPU): details"), "{table}");
    }

    #[test]
    fn a_cpu_only_table_says_so() {
        let results = [JobResult {
            job: "cut (ms)".into(),
            unit: "ms",
            cells: vec![Cell {
                p95: Some(12.0),
                ..cell("CPU", 10.0, true, None)
            }],
        }];
        let table = markdown(&[device("CPU", "cpu")], &results, 1);
        assert!(table.contains("no GPU adapter measured"), "{table}");
        assert!(
            table.contains("| cut (ms) | 10.0 (12.0) | yes |"),
            "{table}"
        );
    }
}
