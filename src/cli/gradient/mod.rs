//! `solidsynth gradient ...`: gradient solid textures (synthesize, vectorize a volume, render or
//! edit a .gsolid). This module holds the subcommands' arguments; each subcommand's checks and
//! report are in its own module.

mod edit;
mod render;
mod synth;
mod vectorize;

use crate::gradient::file::GradientFile;
use crate::gradient::{format, GradientSolid};
use crate::Error;
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum GradientCommand {
    /// Synthesize a gradient solid directly from a 2D exemplar (paper section 4): a periodic
    /// solid of period N (rounded up to a multiple of 4) that tiles space.
    #[command(after_help = super::help::GRADIENT_SYNTH)]
    Synth(SynthArgs),
    /// Fit a gradient solid to a volume (NRRD): per control point, eq. 2's least squares.
    #[command(after_help = super::help::GRADIENT_VECTORIZE)]
    Vectorize(VectorizeArgs),
    /// Render a .gsolid into a volume (NRRD, NumPy, TIFF, KTX2, OpenVDB, VTI or flipbook PNG, by
    /// the output's extension), or with --normal a slice of any orientation as a PNG.
    #[command(after_help = super::help::GRADIENT_RENDER)]
    Render(RenderArgs),
    /// Recolour by strokes (instant editing): voxels similar in place and colour to the strokes
    /// move towards a reference colour; only control points change.
    #[command(after_help = super::help::GRADIENT_EDIT)]
    Edit(EditArgs),
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum SearchArg {
    /// The paper's: E_y (E_z) the nearest to its slice among the N1 = 20 (N2 = 50) patches
    /// most consistent with E_x (and E_y) on their crossbars.
    Crossbar,
    /// E_y (E_z) the most crossbar-consistent among the N1 = 20 (N2 = 50) patches nearest to
    /// its slice.
    CrossbarNearest,
    /// Three independent nearest-patch searches.
    Independent,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Gradient synthesis")]
pub struct SynthArgs {
    /// Exemplar image (PNG, JPEG, ...); without it, the built-in exemplar.
    pub input: Option<PathBuf>,
    /// Period of the solid in voxels (its edge); rounded up to a multiple of 4.
    #[arg(help_heading = "Gradient synthesis", long, value_parser = crate::cli::whole_number_in::<16, { crate::gradient::synth::MAX_SIZE }>)]
    pub size: u32,
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = 0)]
    pub seed: u64,
    /// Direction field orienting the slices: none, constant:X,Y,Z (local z along it) or
    /// cylinder:X,Y,Z (around that axis through the centre; rings, vases).
    #[arg(help_heading = "Gradient synthesis", long, default_value = "none")]
    pub field: String,
    /// How the three slices of a check point are matched.
    #[arg(
        help_heading = "Gradient synthesis",
        long,
        value_enum,
        default_value = "crossbar"
    )]
    pub search: SearchArg,
    /// Nearest-patch search: P > 0 approximate (the paper's ANN step), scanning the P lists (of
    /// about sqrt(candidates), k-means of the patches' projections) nearest to each query; 0
    /// exact (exhaustive: about 4x slower at --size 64 on a 2-core Xeon, CPU backend; the same
    /// quality by `eval`).
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = crate::gradient::synth::DEFAULT_PROBES,
          value_parser = crate::cli::whole_number_in::<0, { crate::gradient::synth::MAX_PROBES }>)]
    pub probes: u32,
    /// Slices matched per check point: 3, or 2 (orthogonal to x and y only) for anisotropic
    /// exemplars such as brick walls or strata.
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = 3)]
    pub slices: u32,
    /// Optimization iterations per level (N_O).
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = 3)]
    pub iterations: u32,
    /// Check points per control cube (N_C).
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = 3)]
    pub check_points: u32,
    /// Colour clusters of the finest level's buckets (N_T).
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = 12)]
    pub clusters: u32,
    /// Finish with the control-point optimization of eq. 3 (all points fitted at once to the
    /// last samples; sizes up to 256).
    #[arg(help_heading = "Gradient synthesis", long)]
    pub optimize: bool,
    /// Conjugate-gradient steps of --optimize.
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = 20, requires = "optimize", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub optimize_iterations: u32,
    /// Region separation (paper 3.2, 4.3): a binary mask image of the exemplar's size (set
    /// where its first channel >= 128, both regions present). Its signed distance is
    /// synthesized as a fourth feature channel, the colour clusters are allocated per region,
    /// and the output is a region solid (sharp boundaries; `gradient render` reads it). Sizes up
    /// to 256; with --optimize, eq. 3 refines both feature sets.
    #[arg(help_heading = "Gradient synthesis", long)]
    pub mask: Option<PathBuf>,
    /// Stored precision of the control values.
    #[arg(help_heading = "Output", long, value_enum, default_value = "u8")]
    pub encoding: format::Encoding,
    #[command(flatten)]
    pub backend: super::BackendArgs,
    /// Output .gsolid.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Editing")]
pub struct EditArgs {
    /// Input .gsolid.
    pub input: PathBuf,
    /// Strokes JSON: {"strokes": [{"position": [x, y, z], "strength": s}, ...]} (voxels; s in [0, 1]).
    #[arg(long)]
    pub strokes: PathBuf,
    /// Reference colour, one number per channel in 0..=255 (e.g. R,G,B).
    #[arg(long)]
    pub color: String,
    /// Propagation alpha of eq. 4 (larger: a more local edit in space and colour).
    #[arg(long, default_value_t = crate::gradient::edit::ALPHA)]
    pub alpha: f64,
    /// Propagation beta of eq. 4 (weight of distance against colour difference).
    #[arg(long, default_value_t = crate::gradient::edit::BETA)]
    pub beta: f64,
    /// Stored precision of the output.
    #[arg(help_heading = "Output", long, value_enum, default_value = "u8")]
    pub encoding: format::Encoding,
    /// Output .gsolid.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Vectorization")]
pub struct VectorizeArgs {
    /// Input volume (NRRD as written by `synth`).
    pub input: PathBuf,
    /// Stored precision of the control values.
    #[arg(help_heading = "Output", long, value_enum, default_value = "u8")]
    pub encoding: format::Encoding,
    /// Then optimize all control values together (eq. 3: least squares against every voxel).
    #[arg(long)]
    pub optimize: bool,
    /// Conjugate-gradient steps of --optimize.
    #[arg(long, default_value_t = 40, requires = "optimize", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub iterations: u32,
    /// Region separation (paper 3.2): a binary mask volume (NRRD, same size; set where its
    /// first channel >= 128). Stores a signed distance field and two feature sets at the control
    /// points next to the boundary, so the boundary stays sharp.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Detail residual (paper 5.4): also store, per colour channel, the standard deviation of
    /// the fitting error as extra channels; renders add position-hashed Gaussian grain of that
    /// size (`gradient render --no-detail` leaves it out). Not with --mask.
    #[arg(long)]
    pub detail: bool,
    /// Output .gsolid.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Rendering")]
pub struct RenderArgs {
    /// Input .gsolid.
    pub input: PathBuf,
    /// Edge of the rendered cube [0, N)^3 (default: the voxels the solid stands for, its
    /// period or its source volume's size); with --normal, the side of the slice in pixels
    /// (default 256). A periodic solid (from `gradient synth`) repeats past its period.
    #[arg(help_heading = "Rendering", long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub size: Option<u32>,
    /// Render a planar slice instead (PNG): its normal NX,NY,NZ, with the conventions of `cut`.
    #[arg(help_heading = "Rendering", long, allow_hyphen_values = true)]
    pub normal: Option<String>,
    /// Slice centre X,Y,Z (voxels; default the solid's centre). With --normal only.
    #[arg(
        help_heading = "Rendering",
        long,
        allow_hyphen_values = true,
        requires = "normal"
    )]
    pub origin: Option<String>,
    /// Slice up direction (default +y, or +z when the normal is along y). With --normal only.
    #[arg(
        help_heading = "Rendering",
        long,
        allow_hyphen_values = true,
        requires = "normal"
    )]
    pub up: Option<String>,
    /// Voxels per slice pixel. With --normal only.
    #[arg(
        help_heading = "Rendering",
        long,
        default_value_t = 1.0,
        requires = "normal"
    )]
    pub spacing: f64,
    /// Region solids: colour each sample with its own region's set only (no anti-aliasing
    /// blend within half a voxel of the boundary).
    #[arg(help_heading = "Rendering", long)]
    pub no_antialias: bool,
    /// Solids with a detail residual: render the smooth part only (no grain).
    #[arg(help_heading = "Rendering", long)]
    pub no_detail: bool,
    #[command(flatten)]
    pub backend: super::BackendArgs,
    /// Output: a volume, its extension picking the format as `synth -o` (.nrrd, .npy, .tif,
    /// .ktx2, .vdb, .vti, .png flipbook); with --normal a PNG slice.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// The volume's format, whatever the extension (not with --normal: a slice is a PNG).
    #[arg(help_heading = "Output", long, value_enum, conflicts_with = "normal")]
    pub format: Option<crate::io::volume_file::VolumeFormat>,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

fn load(path: &Path) -> crate::Result<GradientSolid> {
    match GradientFile::load(path)? {
        GradientFile::Plain(s) => Ok(s),
        GradientFile::Regions(_) => Err(Error::invalid(
            path.display().to_string(),
            "is a region-separated solid; this command takes plain solids only (vectorize \
             without --mask)",
        )),
    }
}

pub fn run(cmd: GradientCommand, quiet: bool) -> anyhow::Result<()> {
    match cmd {
        GradientCommand::Synth(a) => synth::synth(a, quiet),
        GradientCommand::Vectorize(a) => vectorize::vectorize(a, quiet),
        GradientCommand::Edit(a) => edit::edit(a, quiet),
        GradientCommand::Render(a) => render::render(a, quiet),
    }
}
