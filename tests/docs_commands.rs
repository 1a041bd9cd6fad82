//! The documentation's commands run as written, so the docs cannot rot: every `solidsynth ...`
//! line of the fenced `sh` blocks in README.md and docs/*.md, and every example at the end of
//! each subcommand's `--help`. Each block (a file's, a subcommand's) runs in order in its own empty
//! directory holding links to the repository's `assets/`, `examples/` and `tests/`, with the
//! binary first on PATH and one analysis cache for all. `solidsynth serve` (which runs until
//! stopped) is left out; `bench serve` runs.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn binary() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_solidsynth"))
}

/// Whether a documented command is one this test runs (not the server, which never returns).
fn runnable(command: &str) -> bool {
    let words: Vec<&str> = command.split_whitespace().collect();
    words.get(1) != Some(&"serve")
}

/// The `solidsynth ...` lines of `text`'s fenced `sh` blocks.
fn fenced_commands(text: &str) -> Vec<String> {
    let mut commands = Vec::new();
    let mut in_sh = false;
    for line in text.lines() {
        let trimmed = line.trim();
        if let Some(fence) = trimmed.strip_prefix("```") {
            in_sh = !in_sh && matches!(fence.trim(), "sh" | "bash" | "shell");
            continue;
        }
        if in_sh && trimmed.starts_with("solidsynth ") {
            commands.push(trimmed.to_string());
        }
    }
    commands
}

/// The examples at the end of a `--help` text.
fn help_examples(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| l.trim() != "Examples:")
        .skip(1)
        .map(str::trim)
        .take_while(|l| l.starts_with("solidsynth "))
        .map(str::to_string)
        .collect()
}

/// Every subcommand path (`["synth"]`, `["gradient", "render"]`, ...), from `--help` itself.
fn subcommands(prefix: &[String]) -> Vec<Vec<String>> {
    let out = Command::new(binary())
        .args(prefix)
        .arg("--help")
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout).to_string();
    let names: Vec<String> = help
        .lines()
        .skip_while(|l| l.trim() != "Commands:")
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|n| n != "help")
        .collect();
    let mut all = Vec::new();
    for name in names {
        let mut path = prefix.to_vec();
        path.push(name);
        let below = subcommands(&path);
        if below.is_empty() {
            all.push(path);
        } else {
            all.extend(below);
        }
    }
    all
}

fn run_block(what: &str, commands: &[String], cache: &Path) {
    let dir = tempfile::tempdir().unwrap();
    for linked in ["assets", "examples", "tests"] {
        std::os::unix::fs::symlink(repo().join(linked), dir.path().join(linked)).unwrap();
    }
    let bin_dir = binary().parent().unwrap().to_path_buf();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    for command in commands.iter().filter(|c| runnable(c)) {
        let out = Command::new("sh")
            .arg("-c")
            .arg(command)
            .current_dir(dir.path())
            .env("PATH", &path)
            .env("SOLIDSYNTH_CACHE_DIR", cache)
            .env("NO_COLOR", "1")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{what}: `{command}` failed ({}):\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn every_subcommand_help_ends_with_examples_that_run() {
    let cache = tempfile::tempdir().unwrap();
    let all = subcommands(&[]);
    assert!(all.len() >= 25, "found only {all:?}");
    for path in all {
        let out = Command::new(binary())
            .args(&path)
            .arg("--help")
            .output()
            .unwrap();
        let help = String::from_utf8_lossy(&out.stdout);
        let examples = help_examples(&help);
        let name = path.join(" ");
        assert!(
            (1..=4).contains(&examples.len()),
            "`solidsynth {name} --help` has {} examples",
            examples.len()
        );
        assert!(
            !help.contains("[`"),
            "`solidsynth {name} --help` shows rustdoc link syntax"
        );
        // Headings hold their own options: a flattened group's heading must not run on over the
        // options declared after it.
        let backend_section: Vec<&str> = help
            .lines()
            .skip_while(|l| *l != "Backend and GPU:")
            .skip(1)
            .take_while(|l| !l.ends_with(':') || l.starts_with(' '))
            .filter_map(|l| l.trim_start().strip_prefix("--"))
            .collect();
        assert!(
            backend_section
                .iter()
                .all(|o| o.starts_with("backend") || o.starts_with("adapter")),
            "`solidsynth {name} --help` lists other options under Backend and GPU: {backend_section:?}"
        );
        run_block(
            &format!("solidsynth {name} --help"),
            &examples,
            cache.path(),
        );
    }
}

#[test]
fn the_tools_help_names_exit_codes_and_environment() {
    let out = Command::new(binary()).arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "Exit codes:",
        "130",
        "Environment:",
        "SOLIDSYNTH_LOG",
        "NO_COLOR",
    ] {
        assert!(help.contains(needle), "--help lacks {needle}");
    }
}

#[test]
fn fenced_commands_in_readme_and_docs_run() {
    let cache = tempfile::tempdir().unwrap();
    let mut files = vec![repo().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(repo().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    let mut total = 0;
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        let commands = fenced_commands(&text);
        total += commands.len();
        run_block(&file.display().to_string(), &commands, cache.path());
    }
    assert!(total >= 10, "only {total} documented commands found");
}

#[test]
fn the_extractors_find_what_they_should() {
    let text = "x\n```sh\nsolidsynth synth --size 8 -o a.nrrd\ncargo run\n```\n```text\nsolidsynth cut\n```\n";
    assert_eq!(
        fenced_commands(text),
        ["solidsynth synth --size 8 -o a.nrrd"]
    );
    let help = "Usage\n\nExamples:\n  solidsynth a\n  solidsynth b\n\nMore";
    assert_eq!(help_examples(help), ["solidsynth a", "solidsynth b"]);
    assert!(!runnable("solidsynth serve --port 1"));
    assert!(runnable("solidsynth bench serve --clients 2"));
}
