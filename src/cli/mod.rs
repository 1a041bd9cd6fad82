//! The `solidsynth` command line: argument parsing and the commands.

pub mod analyze;
pub mod bench;
mod bench_child;
pub mod bench_compare;
pub mod cut;
mod entry;
pub mod eval;
pub mod gradient;
mod help;
pub mod inspect;
pub mod lapped;
pub mod lapped_bench;
pub mod output;
pub mod ptm;
pub mod ptm_bench;
pub mod region_zarr;
pub mod serve;
pub mod serve_bench;
pub mod surface;
pub mod synth;
mod triples;

use clap::{Args, Parser, Subcommand};

use crate::backend::{BackendChoice, Compute};
use crate::gpu::GpuOptions;
pub use entry::main;

#[derive(Parser, Debug)]
#[command(
    name = "solidsynth",
    version,
    about = "Solid texture synthesis from 2D exemplars, on the GPU",
    after_help = help::TOOL
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Less output: warnings and errors only.
    #[arg(long, short, global = true)]
    pub quiet: bool,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Analyse exemplar(s): pyramids, PCA, 3D candidates; writes a .ssa file.
    #[command(after_help = help::ANALYZE)]
    Analyze(analyze::AnalyzeArgs),
    /// Score a volume against its exemplar: histograms, patch coherence and completeness,
    /// gradient orientations and sharpness, sliced Wasserstein distances of patches at three
    /// scales and the power spectrum, per axis, with floors; optionally a contact sheet.
    #[command(after_help = help::EVAL)]
    Eval(eval::EvalArgs),
    /// Synthesize the solid texture box [0, N)^3, or a tileable solid, as a volume (NRRD, NumPy,
    /// TIFF, KTX2, OpenVDB, VTI or flipbook PNG); optional PNG slices, flipbook, sheet.
    #[command(after_help = help::SYNTH)]
    Synth(synth::SynthArgs),
    /// Synthesize any box of the infinite solid (same voxels as in any larger box).
    #[command(after_help = help::REGION)]
    Region(synth::RegionArgs),
    /// A planar cut of the solid (any orientation) as a PNG; --repeat measures warm latency.
    #[command(after_help = help::CUT)]
    Cut(cut::CutArgs),
    /// The solid baked onto a mesh surface: a UV atlas texture (binary glTF, or OBJ + MTL + PNG).
    #[command(after_help = help::SURFACE)]
    Surface(surface::SurfaceArgs),
    /// Describe a .ssa file and write its candidate slab as a PNG.
    #[command(after_help = help::INSPECT)]
    Inspect(inspect::InspectArgs),
    /// Gradient solid textures: synthesize, vectorize, render and edit gradient solids (.gsolid).
    #[command(subcommand)]
    Gradient(gradient::GradientCommand),
    /// Relightable textures (polynomial texture maps): capture, fit, synthesize, relight.
    #[command(subcommand)]
    Ptm(ptm::PtmCommand),
    /// Lapped solid textures: fill a mesh with pasted solid exemplars; cut, render, bake.
    #[command(subcommand)]
    Lapped(lapped::LappedCommand),
    /// The interactive viewer: a local web page (built into the binary) to cut through the
    /// solid, and its HTTP API.
    #[command(after_help = help::SERVE)]
    Serve(serve::ServeArgs),
    /// Benchmarks printed as tables.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// List the GPU adapters wgpu can see.
    #[command(after_help = help::ADAPTERS)]
    Adapters(AdaptersArgs),
    /// Shell completions (bash, zsh, fish, elvish, powershell) on stdout.
    #[command(after_help = help::COMPLETIONS)]
    Completions(CompletionsArgs),
    /// Man pages (roff): solidsynth.1 and one per subcommand, into a directory.
    #[command(after_help = help::MAN)]
    Man(ManArgs),
}

#[derive(Args, Debug)]
pub struct AdaptersArgs {
    /// Print JSON instead of lines.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

#[derive(Args, Debug)]
pub struct ManArgs {
    /// Directory for the pages (created if missing; existing pages of these names are replaced).
    #[arg(short, long)]
    pub output: std::path::PathBuf,
}

/// Backend flags shared by the commands that run kernels.
#[derive(Args, Debug, Clone)]
#[command(next_help_heading = "Backend and GPU")]
pub struct BackendArgs {
    /// Where kernels run: gpu (any Vulkan adapter, lavapipe included), cpu, or auto.
    #[arg(long, value_enum, default_value = "auto")]
    pub backend: BackendChoice,
    /// Use the adapter whose name contains this (case-insensitive).
    #[arg(long, env = "SOLIDSYNTH_ADAPTER")]
    pub adapter: Option<String>,
}

impl BackendArgs {
    /// The GPU options of these arguments (`--adapter` over the environment's).
    pub fn gpu_options(&self) -> GpuOptions {
        let mut opts = GpuOptions::from_env();
        if self.adapter.is_some() {
            opts.adapter_filter = self.adapter.clone();
        }
        opts
    }

    pub fn open(&self) -> crate::Result<Compute> {
        let compute = Compute::open(self.backend, &self.gpu_options())?;
        tracing::info!("backend: {}", compute.describe());
        Ok(compute)
    }
}

/// `args` (the process's, without the program) without the leading subcommand names
/// (`ptm capture`), found by walking clap's command tree: what is left are the flags and values.
pub fn command_arguments(args: Vec<std::ffi::OsString>) -> Vec<std::ffi::OsString> {
    use clap::CommandFactory;
    let mut command = Cli::command();
    let mut names = Vec::new();
    for (i, arg) in args.iter().enumerate() {
        let Some(word) = arg.to_str() else { break };
        if word.starts_with('-') {
            // A global flag before the subcommand (`-q`).
            continue;
        }
        match command.find_subcommand(word) {
            Some(sub) => {
                command = sub.clone();
                names.push(i);
            }
            None => break,
        }
    }
    args.into_iter()
        .enumerate()
        .filter(|(i, _)| !names.contains(i))
        .map(|(_, a)| a)
        .collect()
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Analyze(a) => analyze::run(a, cli.quiet),
        Command::Inspect(a) => inspect::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Synth(a) => synth::run(a, cli.quiet),
        Command::Region(a) => synth::run_region(a, cli.quiet),
        Command::Cut(a) => cut::run(a, cli.quiet),
        Command::Surface(a) => surface::run(a, cli.quiet),
        Command::Gradient(g) => gradient::run(g, cli.quiet),
        Command::Ptm(p) => ptm::run(p, cli.quiet),
        Command::Lapped(l) => lapped::run(l, cli.quiet),
        Command::Serve(a) => serve::run(a, cli.quiet),
        Command::Bench(b) => bench::run(b),
        Command::Adapters(a) => adapters(a),
        Command::Completions(a) => {
            use clap::CommandFactory;
            let mut command = Cli::command();
            clap_complete::generate(a.shell, &mut command, "solidsynth", &mut std::io::stdout());
            Ok(())
        }
        Command::Man(a) => man_pages(&a.output),
    }
}

fn adapters(args: AdaptersArgs) -> anyhow::Result<()> {
    let list = crate::gpu::context::list_adapters();
    if args.json {
        let adapters: Vec<AdapterSummary> = list
            .iter()
            .map(|a| AdapterSummary {
                name: &a.name,
                device_type: format!("{:?}", a.device_type).to_lowercase(),
                backend: format!("{:?}", a.backend).to_lowercase(),
                driver: &a.driver,
                driver_info: &a.driver_info,
            })
            .collect();
        output::print_summary(&AdaptersSummary { adapters });
        return Ok(());
    }
    if list.is_empty() {
        println!("no Vulkan adapters (install mesa-vulkan-drivers for lavapipe)");
    }
    for a in list {
        println!(
            "{} ({:?}, {:?}, driver {} {})",
            a.name, a.device_type, a.backend, a.driver, a.driver_info
        );
    }
    Ok(())
}

/// Write `solidsynth.1` and a page per subcommand (`solidsynth-synth.1`, ...) into `dir`.
fn man_pages(dir: &std::path::Path) -> anyhow::Result<()> {
    use clap::CommandFactory;
    if dir.exists() && !dir.is_dir() {
        return Err(crate::Error::invalid(
            format!("-o {}", dir.display()),
            "exists and is not a directory; man pages are written into a directory",
        )
        .into());
    }
    // The pages are made in a scratch directory, then staged beside their targets and put in
    // place together: a page that cannot be written leaves the others as they were.
    let scratch = tempfile::tempdir().map_err(|e| crate::Error::io(std::env::temp_dir(), e))?;
    clap_mangen::generate_to(Cli::command(), scratch.path())
        .map_err(|e| crate::Error::io(scratch.path(), e))?;
    let mut pages: Vec<_> = std::fs::read_dir(scratch.path())
        .and_then(|entries| entries.map(|e| e.map(|e| e.file_name())).collect())
        .map_err(|e| crate::Error::io(scratch.path(), e))?;
    pages.sort();
    for name in &pages {
        let target = dir.join(name);
        if target.is_dir() {
            return Err(crate::Error::invalid(
                format!("-o {}", dir.display()),
                format!("holds a directory {}, where a page goes", target.display()),
            )
            .into());
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| {
        crate::Error::invalid(
            format!("-o {}", dir.display()),
            format!(
                "cannot make the directory ({})",
                crate::error::io_problem(&e)
            ),
        )
    })?;
    let mut outputs = crate::io::atomic::Outputs::new();
    for name in &pages {
        let page = std::fs::read(scratch.path().join(name))
            .map_err(|e| crate::Error::io(scratch.path().join(name), e))?;
        outputs.write_file(&dir.join(name), &page)?;
    }
    outputs.commit()?;
    Ok(())
}

/// A whole-number flag's value: numbers past u32 are refused with the flag's own range
/// (`MIN..=MAX`) rather than the type's; values within u32 are checked by the command, in the
/// same words, with the value named.
pub fn whole_number_in<const MIN: u32, const MAX: u32>(text: &str) -> Result<u32, String> {
    let expected = || format!("expected a whole number in {MIN}..={MAX}");
    let value = text.trim().parse::<u64>().map_err(|_| expected())?;
    u32::try_from(value).map_err(|_| expected())
}

/// A command's progress on stderr ([`output::Progress`]: a bar on a terminal, a line per stage
/// otherwise, nothing when `quiet`).
pub fn progress_bar(quiet: bool) -> output::Progress {
    output::Progress::new(quiet)
}

/// `adapters --json`.
#[derive(serde::Serialize)]
struct AdaptersSummary<'a> {
    adapters: Vec<AdapterSummary<'a>>,
}

#[derive(serde::Serialize)]
struct AdapterSummary<'a> {
    name: &'a str,
    /// `discretegpu`, `integratedgpu`, `virtualgpu`, `cpu` or `other`.
    device_type: String,
    /// `vulkan`, ...
    backend: String,
    driver: &'a str,
    driver_info: &'a str,
}

#[cfg(test)]
mod tests {
    use clap::ValueEnum;

    /// The library's parsers (what the Python package uses) accept exactly the flags' spellings.
    fn parses_every_flag_spelling<T>()
    where
        T: ValueEnum + std::str::FromStr + PartialEq + std::fmt::Debug,
    {
        for variant in T::value_variants() {
            let name = variant.to_possible_value().unwrap().get_name().to_string();
            assert_eq!(name.parse::<T>().ok().as_ref(), Some(variant), "{name}");
        }
        assert!("no-such-value".parse::<T>().is_err());
    }

    #[test]
    fn library_parsers_match_the_command_line() {
        parses_every_flag_spelling::<crate::backend::BackendChoice>();
        parses_every_flag_spelling::<crate::lazy::CandidateMode>();
        parses_every_flag_spelling::<crate::analysis::frame::InputFrame>();
        for mode in crate::lazy::CandidateMode::value_variants() {
            assert_eq!(
                mode.to_string(),
                mode.to_possible_value().unwrap().get_name()
            );
        }
    }
}
