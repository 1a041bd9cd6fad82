//! What the command line prints on stderr: progress (a bar on a terminal, one line per stage
//! elsewhere), and log lines that go around the bar instead of breaking it, in colour only on a
//! terminal without `NO_COLOR`.

use std::io::{IsTerminal, Write};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Whether stderr is a terminal (bars, colour) or a file or pipe (plain lines).
pub fn stderr_is_terminal() -> bool {
    std::io::stderr().is_terminal()
}

/// ANSI colour in log lines: on a terminal, unless `NO_COLOR` is set to anything non-empty
/// (<https://no-color.org>).
pub fn use_color() -> bool {
    stderr_is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

/// The version of the `--json` summaries' layout, in every summary as `"schema"`: raised when a
/// key is removed or changes meaning (new keys keep it).
pub const SUMMARY_SCHEMA: u32 = 1;

/// Print a command's `--json` summary on stdout, with the summary format's version
/// ([`SUMMARY_SCHEMA`]) added.
pub fn print_json(mut summary: serde_json::Value) {
    summary["schema"] = SUMMARY_SCHEMA.into();
    println!("{summary}");
}

/// Print a command's typed `--json` summary ([`print_json`]).
pub fn print_summary(summary: &impl serde::Serialize) {
    print_json(serde_json::to_value(summary).expect("summaries serialize"));
}

/// The median of `samples` (at least one): for an even count the upper of the two middle values,
/// so that it is always one of the measured samples.
pub fn median(samples: &[f64]) -> f64 {
    let mut sorted = samples.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

/// The `p`-th quantile (0 < p <= 1) of `samples` by the nearest-rank method; NaN when there are
/// none. For an even count its 0.5 is the lower middle sample, where [`median`] takes the upper.
pub fn percentile(samples: &[f64], p: f64) -> f64 {
    if samples.is_empty() {
        return f64::NAN;
    }
    let mut sorted = samples.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[((sorted.len() as f64 * p).ceil() as usize).clamp(1, sorted.len()) - 1]
}

/// Repeated requests' latencies in a summary (`--repeat`): the median and the 95th percentile
/// (nearest rank) of the warm requests (all but the first, when there are several), and the first
/// (cold) one, which pays for building the session's pipelines and caches.
#[derive(Clone, Copy, serde::Serialize)]
pub struct Latencies {
    pub median_ms: f64,
    pub p95_ms: f64,
    pub first_ms: f64,
}

impl Latencies {
    /// Of `ms`, in request order (at least one).
    pub fn of(ms: &[f64]) -> Latencies {
        let warm = if ms.len() > 1 { &ms[1..] } else { ms };
        Latencies {
            median_ms: median(warm),
            p95_ms: percentile(warm, 0.95),
            first_ms: ms[0],
        }
    }

    /// What the median and p95 of `repeat` requests cover, for messages.
    pub fn over(repeat: u32) -> String {
        match repeat {
            1 => "of one cut".into(),
            2 => "of the cut after the first".into(),
            n => format!("over the {} cuts after the first", n - 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{median, percentile, Latencies};

    #[test]
    fn median_and_percentiles_are_measured_samples() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        // An even count gives the upper middle sample, not an average of two.
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 3.0);
        let hundred: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        assert_eq!(percentile(&hundred, 0.5), 50.0);
        assert_eq!(percentile(&hundred, 0.95), 95.0);
        assert_eq!(percentile(&hundred, 0.99), 99.0);
        assert_eq!(percentile(&[7.0], 0.95), 7.0);
        assert!(percentile(&[], 0.5).is_nan());
    }

    #[test]
    fn latencies_leave_out_the_cold_first_request() {
        let t = Latencies::of(&[100.0, 1.0, 3.0, 2.0]);
        assert_eq!((t.median_ms, t.p95_ms, t.first_ms), (2.0, 3.0, 100.0));
        let one = Latencies::of(&[5.0]);
        assert_eq!((one.median_ms, one.p95_ms, one.first_ms), (5.0, 5.0, 5.0));
    }
}

/// A kernel's time in a summary (`--profile`).
#[derive(serde::Serialize)]
pub struct KernelTime {
    pub seconds: f64,
    pub calls: u64,
}

/// The progress bar on screen now, if any: log lines are printed around it.
static ACTIVE_BAR: Mutex<Option<indicatif::ProgressBar>> = Mutex::new(None);

/// A command's progress: a bar on a terminal; with stderr redirected, one line per stage
/// (each new message, with the seconds since the start); nothing with `--quiet` or `--json`.
#[derive(Clone)]
pub struct Progress {
    bar: indicatif::ProgressBar,
    lines: Option<Arc<StageLines>>,
}

struct StageLines {
    start: Instant,
    /// The last message and when the last line was printed.
    last: Mutex<(String, f64)>,
}

impl Progress {
    pub fn new(quiet: bool) -> Progress {
        if quiet {
            return Progress {
                bar: indicatif::ProgressBar::hidden(),
                lines: None,
            };
        }
        if !stderr_is_terminal() {
            return Progress {
                bar: indicatif::ProgressBar::hidden(),
                lines: Some(Arc::new(StageLines {
                    start: Instant::now(),
                    last: Mutex::new((String::new(), f64::NEG_INFINITY)),
                })),
            };
        }
        let bar = indicatif::ProgressBar::new(1000);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{elapsed:>4} [{bar:30}] {msg}")
                .expect("a valid template")
                .progress_chars("=> "),
        );
        *ACTIVE_BAR.lock().unwrap_or_else(|e| e.into_inner()) = Some(bar.clone());
        Progress { bar, lines: None }
    }

    pub fn set_message(&self, message: impl Into<String>) {
        let message = message.into();
        if let Some(lines) = &self.lines {
            let mut last = lines.last.lock().unwrap_or_else(|e| e.into_inner());
            // Stages are reported many times over ("level 3: correction") and counters tick
            // ("120/400 tets covered"): a line when the words before any number change, else at
            // most one a second.
            let words = |m: &str| {
                m.split(|c: char| c.is_ascii_digit())
                    .next()
                    .unwrap_or("")
                    .to_owned()
            };
            let now = lines.start.elapsed().as_secs_f64();
            if message != last.0 && (words(&message) != words(&last.0) || now - last.1 >= 1.0) {
                eprintln!("{now:>7.1} s  {message}");
                last.1 = now;
            }
            last.0 = message;
        } else {
            self.bar.set_message(message);
        }
    }

    pub fn set_position(&self, position: u64) {
        self.bar.set_position(position);
    }

    pub fn set_length(&self, length: u64) {
        self.bar.set_length(length);
    }

    /// Progress as a fraction with a stage message (the library's progress callbacks).
    pub fn report(&self, stage: &str, fraction: f32) {
        self.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
        self.set_message(stage);
    }

    pub fn finish_and_clear(&self) {
        self.bar.finish_and_clear();
        let mut active = ACTIVE_BAR.lock().unwrap_or_else(|e| e.into_inner());
        if active.as_ref().is_some_and(|b| b.is_finished()) {
            *active = None;
        }
    }
}

/// The log's writer: stderr, with the active progress bar (if any) cleared while a line is
/// written and redrawn after it.
pub struct LogWriter;

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for LogWriter {
    type Writer = LogLine;

    fn make_writer(&'a self) -> LogLine {
        LogLine(Vec::new())
    }
}

/// One log line, written whole when dropped.
pub struct LogLine(Vec<u8>);

impl Write for LogLine {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for LogLine {
    fn drop(&mut self) {
        if self.0.is_empty() {
            return;
        }
        let write = || {
            let _ = std::io::stderr().write_all(&self.0);
        };
        let active = ACTIVE_BAR.lock().unwrap_or_else(|e| e.into_inner()).clone();
        match active {
            Some(bar) if !bar.is_finished() => bar.suspend(write),
            _ => write(),
        }
    }
}

/// A benchmark's results: its table on stdout, or with `--json` one JSON document holding the
/// same rows (typed, as `row` receives them), the benchmark's name and its settings.
pub struct BenchReport {
    json: bool,
    bench: &'static str,
    settings: serde_json::Value,
    rows: Vec<serde_json::Value>,
    notes: Vec<String>,
}

impl BenchReport {
    pub fn new(bench: &'static str, json: bool, settings: impl serde::Serialize) -> BenchReport {
        BenchReport {
            json,
            bench,
            settings: serde_json::to_value(settings).expect("settings serialize"),
            rows: Vec::new(),
            notes: Vec::new(),
        }
    }

    /// A line of the table (printed now, unless the report is JSON).
    pub fn line(&self, text: impl AsRef<str>) {
        if !self.json {
            println!("{}", text.as_ref());
        }
    }

    /// One measured row, with its table line.
    pub fn row(&mut self, row: impl serde::Serialize, text: impl AsRef<str>) {
        self.line(text);
        self.rows
            .push(serde_json::to_value(row).expect("benchmark rows serialize"));
    }

    /// A remark that belongs to the results (an adapter, a mismatch), in both forms.
    pub fn note(&mut self, text: impl Into<String>) {
        let text = text.into();
        self.line(&text);
        self.notes.push(text);
    }

    /// Print the JSON document (with `--json`; the table is already out otherwise).
    pub fn finish(self) {
        if self.json {
            print_json(serde_json::json!({
                "bench": self.bench, "settings": self.settings, "rows": self.rows,
                "notes": self.notes,
            }));
        }
    }
}
