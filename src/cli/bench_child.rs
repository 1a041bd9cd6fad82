//! The benchmarks' child processes: each run is a fresh `solidsynth` whose `--json` summary
//! the benchmark reads.

use std::process::Command;

/// A child that refused its arguments (exit 2). The benchmark passed it the user's values, so
/// the refusal is the user's input too: the benchmark exits 2 with the child's message.
#[derive(Debug, thiserror::Error)]
#[error("{job}: {message}")]
pub struct ChildRefused {
    /// The child's command, as the benchmark describes it.
    pub job: String,
    /// The child's error message, without its "error: ".
    pub message: String,
}

/// Run `cmd` and parse its standard output as JSON. A failure names `job` and carries the
/// child's error message; a refusal (exit 2) is a [`ChildRefused`].
pub fn run_json(cmd: &mut Command, job: &str) -> anyhow::Result<serde_json::Value> {
    let out = cmd.output()?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        // The message is the last "error: " line and what follows (log lines come before it).
        let lines: Vec<&str> = stderr.trim().lines().collect();
        let message = match lines.iter().rposition(|l| l.starts_with("error: ")) {
            Some(i) => lines[i..].join("\n")["error: ".len()..].to_string(),
            None => lines.join("\n"),
        };
        if out.status.code() == Some(2) {
            return Err(ChildRefused {
                job: job.to_string(),
                message,
            }
            .into());
        }
        anyhow::bail!("{job} failed ({}): {message}", out.status);
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| anyhow::anyhow!("{job}: its --json summary does not parse: {e}"))
}
