//! `solidsynth gradient ...`: gradient solid textures (vectorize a volume, render or edit a
//! .gsolid).
//!
//! Length: about 720 lines of the gradient subcommands' arguments, checks and reports (no engine
//! logic).

use super::output::print_summary;
use crate::backend::Compute;
use crate::gradient::file::GradientFile;
use crate::gradient::regions::{self, Blend, RegionSolid};
use crate::gradient::Query;
use crate::gradient::{detail, edit, format, vectorize, GradientSolid};
use crate::io::{atomic, nrrd};
use crate::Error;
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum GradientCommand {
    /// Synthesize a gradient solid directly from a 2D exemplar (paper section 4): a periodic
    /// solid of period N (rounded up to a multiple of 4) that tiles space.
    #[command(after_help = super::help::GRADIENT_SYNTH)]
    Synth(SynthArgs),
    /// Fit a gradient solid to a volume (NRRD): per control point, eq. 2's least squares.
    #[command(after_help = super::help::GRADIENT_VECTORIZE)]
    Vectorize(VectorizeArgs),
    /// Render a .gsolid into a volume (NRRD).
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
    #[arg(help_heading = "Gradient synthesis", long)]
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
    /// exact (exhaustive, about 3x slower; the same quality by `eval`).
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = crate::gradient::synth::DEFAULT_PROBES)]
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
    #[arg(help_heading = "Gradient synthesis", long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=1000))]
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
    /// Reference colour, one number per channel (e.g. R,G,B in 0..255).
    #[arg(long)]
    pub color: String,
    /// Propagation alpha of eq. 4 (larger: a more local edit in space and colour).
    #[arg(long, default_value_t = edit::ALPHA)]
    pub alpha: f64,
    /// Propagation beta of eq. 4 (weight of distance against colour difference).
    #[arg(long, default_value_t = edit::BETA)]
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
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u32).range(1..=1000))]
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
    /// Edge of the rendered cube [0, N)^3 (default: the solid's extent); with --normal, the
    /// side of the slice in pixels (default 256).
    #[arg(help_heading = "Rendering", long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub size: Option<u32>,
    /// Render a planar slice instead (PNG): its normal NX,NY,NZ, with the conventions of `cut`.
    #[arg(help_heading = "Rendering", long, allow_hyphen_values = true)]
    pub normal: Option<String>,
    /// Slice centre X,Y,Z (voxels; default the solid's centre).
    #[arg(help_heading = "Rendering", long, allow_hyphen_values = true)]
    pub origin: Option<String>,
    /// Slice up direction (default +y, or +z when the normal is along y).
    #[arg(help_heading = "Rendering", long, allow_hyphen_values = true)]
    pub up: Option<String>,
    /// Voxels per slice pixel.
    #[arg(help_heading = "Rendering", long, default_value_t = 1.0)]
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
    /// .ktx2, .vti, .png flipbook); with --normal a PNG slice.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// The volume's format, whatever the extension.
    #[arg(help_heading = "Output", long, value_enum)]
    pub format: Option<crate::io::volume_file::VolumeFormat>,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

/// `gradient render --normal ...`: a slice of any orientation as a PNG (the `cut` conventions:
/// pixel (i, j) samples origin + (i + 0.5 - N/2) s u + (j + 0.5 - N/2) s v, at that point, not at
/// a voxel: the solid is continuous).
fn render_slice(
    a: &RenderArgs,
    solid: &GradientFile,
    normal: &str,
    quiet: bool,
) -> anyhow::Result<()> {
    let centre = solid.extent().map(|e| (e as f64 - 1.0) / 2.0);
    let spec = crate::lazy::cut::CutSpec {
        origin: match &a.origin {
            Some(o) => super::cut::triple(o, "--origin")?,
            None => centre,
        },
        normal: super::cut::triple(normal, "--normal")?,
        up: a
            .up
            .as_deref()
            .map(|u| super::cut::triple(u, "--up"))
            .transpose()?,
        size: a.size.unwrap_or(256),
        spacing: a.spacing,
    };
    let (u, v, _) = spec.frame()?;
    let (n, s) = (spec.size as f64, spec.spacing);
    let o = glam::DVec3::from_array(spec.origin) + (0.5 - n / 2.0) * s * (u + v);
    let f = |d: glam::DVec3| [d.x as f32, d.y as f32, d.z as f32];
    let query = Query::Grid {
        origin: f(o),
        a: f(u * s),
        b: f(v * s),
        c: [0.0; 3],
        n: [spec.size, spec.size, 1],
    };
    let compute = a.backend.open()?;
    let start = Instant::now();
    let values = solid.eval_u8(&query, &compute, blend_of(a), !a.no_detail)?;
    let c = solid.channels() as usize;
    let img = image::RgbaImage::from_fn(spec.size, spec.size, |x, y| {
        let i = (y as usize * spec.size as usize + x as usize) * c;
        let px = &values[i..i + c];
        match c {
            1 | 2 => image::Rgba([px[0], px[0], px[0], 255]),
            _ => image::Rgba([px[0], px[1], px[2], if c > 3 { px[3] } else { 255 }]),
        }
    });
    atomic::save_png(&a.output, &img)?;
    if !quiet {
        eprintln!(
            "rendered a {0}x{0} slice in {1:.3} s -> {2}",
            spec.size,
            start.elapsed().as_secs_f64(),
            a.output.display()
        );
    }
    Ok(())
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

fn synth(a: SynthArgs, quiet: bool) -> anyhow::Result<()> {
    use crate::gradient::synth::{self, Field, GradientSynthParams, SliceSearch};
    atomic::check_output_path(&a.output, "-o")?;
    let exemplar = match &a.input {
        Some(path) => crate::exemplar::load_image(path, &path.display().to_string())?,
        None => crate::exemplar::default_exemplar(),
    };
    let name = a
        .input
        .as_ref()
        .map_or("built-in exemplar".to_string(), |p| p.display().to_string());
    crate::exemplar::check_exemplar_size(&exemplar, &name)?;
    let field = Field::parse(&a.field).ok_or_else(|| {
        Error::invalid(
            format!("--field {}", a.field),
            "expected none, constant:X,Y,Z or cylinder:X,Y,Z with a non-zero direction",
        )
    })?;
    let params = GradientSynthParams {
        seed: a.seed,
        size: a.size,
        iterations: a.iterations,
        check_points: a.check_points,
        clusters: a.clusters,
        search: match a.search {
            SearchArg::Crossbar => SliceSearch::Crossbar { n1: 20, n2: 50 },
            SearchArg::CrossbarNearest => SliceSearch::CrossbarNearest { n1: 20, n2: 50 },
            SearchArg::Independent => SliceSearch::Independent,
        },
        field,
        matched_slices: a.slices,
        optimize_iterations: if a.optimize { a.optimize_iterations } else { 0 },
        probes: (a.probes > 0).then_some(a.probes),
        ..Default::default()
    };
    params.validate()?;
    let side = params.min_exemplar_side();
    if exemplar.width < side || exemplar.height < side {
        return Err(Error::invalid(
            name,
            format!(
                "is {}x{}; gradient synthesis needs at least {side}x{side} pixels (its coarsest \
                 patches span that much)",
                exemplar.width, exemplar.height
            ),
        )
        .into());
    }
    let masked = match &a.mask {
        Some(path) => {
            params.validate_with_mask()?;
            let what = format!("--mask {}", path.display());
            let bytes = std::fs::read(path)
                .map_err(|e| Error::invalid(&what, format!("cannot read the file: {e}")))?;
            let mask = crate::exemplar::decode_image(&bytes, &what)?;
            Some(synth::MaskedExemplar::new(&exemplar, &mask, &what)?)
        }
        None => None,
    };
    let compute = a.backend.open()?;
    let bar = super::progress_bar(quiet || a.json);
    bar.set_length(1000);
    let progress = |msg: &str, f: f32| {
        bar.report(msg, f);
    };
    let (bytes, grid, report) = match &masked {
        Some(m) => {
            let (rs, report) = synth::synthesize_regions(m, &params, &compute, &progress)?;
            (rs.to_bytes(a.encoding), rs.positive.dims, report)
        }
        None => {
            let (solid, report) = synth::synthesize(&exemplar, &params, &compute, &progress)?;
            let solid = solid.to_gradient_solid()?;
            (format::to_bytes(&solid, a.encoding), solid.dims, report)
        }
    };
    bar.finish_and_clear();
    atomic::write_file(&a.output, &bytes)?;
    let period = params.cells() * crate::gradient::SPACING;
    // The file against the RGB volume it stands for (a period, 3 bytes per voxel).
    let fraction = bytes.len() as f64 / (3.0 * (period as f64).powi(3));
    if a.json {
        let levels: Vec<_> = report
            .levels
            .iter()
            .map(|l| GradientLevelSummary {
                spacing: l.spec.spacing,
                size: l.spec.size,
                candidates: l.candidates,
                pca_energy: l.pca_energy,
                prepare_seconds: l.prepare_seconds,
                match_seconds: l.match_seconds,
                update_seconds: l.update_seconds,
                refitted: l.refitted,
            })
            .collect();
        print_summary(&GradientSynthSummary {
            output: &a.output,
            grid,
            period,
            seconds: report.seconds,
            bytes: bytes.len(),
            fraction_of_volume: fraction,
            levels,
            optimize_seconds: report.optimize_seconds,
            optimize_rms: [report.optimize_rms.0, report.optimize_rms.1],
            regions: report.regions.as_ref(),
            backend: compute.describe(),
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
        });
    } else if !quiet {
        for l in &report.levels {
            eprintln!(
                "level N={} spacing {}: {} patches (PCA keeps {:.1}%), prepare {:.2} s, match \
                 {:.2} s, update {:.2} s",
                l.spec.size,
                l.spec.spacing,
                l.candidates,
                l.pca_energy * 100.0,
                l.prepare_seconds,
                l.match_seconds,
                l.update_seconds
            );
        }
        if a.optimize {
            eprintln!(
                "final optimization (eq. 3): RMS to the samples {:.2} -> {:.2} in {:.2} s",
                report.optimize_rms.0, report.optimize_rms.1, report.optimize_seconds
            );
        }
        if let Some(r) = &report.regions {
            eprintln!(
                "region separation in {:.2} s: {} of {} control points split, {:.1}% of the \
                 volume positive (exemplar mask: {:.1}%), {:.2}% of the voxels without samples",
                r.seconds,
                r.split_points,
                r.points,
                r.positive_fraction * 100.0,
                r.exemplar_positive_fraction * 100.0,
                r.empty_buckets * 100.0
            );
        }
        eprintln!(
            "synthesized a {}gradient solid of period {period} ({grid:?} control points) in \
             {:.2} s ({}), {} bytes ({:.1}% of the RGB volume) -> {}",
            if masked.is_some() { "region " } else { "" },
            report.seconds,
            compute.describe(),
            bytes.len(),
            fraction * 100.0,
            a.output.display()
        );
    }
    Ok(())
}

fn blend_of(a: &RenderArgs) -> Blend {
    if a.no_antialias {
        Blend::Exact
    } else {
        Blend::Antialiased
    }
}

/// `gradient vectorize --mask`: region separation; reports the stored file's error with and
/// without the anti-aliasing blend, and the plain fit's for comparison.
fn vectorize_with_mask(
    a: &VectorizeArgs,
    volume: &crate::volume::Volume,
    mask_path: &Path,
    quiet: bool,
) -> anyhow::Result<()> {
    let mask = nrrd::load(mask_path)?;
    let start = Instant::now();
    let mut rs = regions::vectorize_regions(volume, &mask, &mask_path.display().to_string())?;
    if a.optimize {
        rs.optimize(volume, a.iterations as usize);
    }
    let fit_s = start.elapsed().as_secs_f64();
    let bytes = rs.to_bytes(a.encoding);
    let stored = RegionSolid::from_bytes(&bytes, "encoded solid")?;
    let n = volume.dims();
    let exact = vectorize::rms(&stored.render(n, &Compute::Cpu, Blend::Exact)?, volume);
    let aa = vectorize::rms(
        &stored.render(n, &Compute::Cpu, Blend::Antialiased)?,
        volume,
    );
    // The comparison: the plain fit with the same refinement.
    let mut plain_fit = vectorize::vectorize(volume)?;
    if a.optimize {
        vectorize::optimize(&mut plain_fit, volume, a.iterations as usize);
    }
    let plain_solid = format::from_bytes(&format::to_bytes(&plain_fit, a.encoding), "plain solid")?;
    let plain = vectorize::rms(&vectorize::render(&plain_solid, n), volume);
    let fraction = bytes.len() as f64 / volume.data.len() as f64;
    atomic::write_file(&a.output, &bytes)?;
    if a.json {
        print_summary(&VectorizeSummary {
            output: &a.output,
            grid: rs.positive.dims,
            split_points: Some(rs.split_points()),
            rms: exact,
            rms_antialiased: Some(aa),
            rms_without_regions: Some(plain),
            seconds: fit_s,
            bytes: bytes.len(),
            fraction_of_volume: fraction,
        });
    } else if !quiet {
        eprintln!(
            "vectorized {}x{}x{} with regions into a {:?} control grid ({} split points) in \
             {fit_s:.2} s: RMS error {exact:.2} ({aa:.2} anti-aliased; {plain:.2} without \
             regions), {} bytes ({:.1}% of the volume) -> {}",
            n[0],
            n[1],
            n[2],
            rs.positive.dims,
            rs.split_points(),
            bytes.len(),
            fraction * 100.0,
            a.output.display()
        );
    }
    Ok(())
}

pub fn run(cmd: GradientCommand, quiet: bool) -> anyhow::Result<()> {
    match cmd {
        GradientCommand::Synth(a) => synth(a, quiet)?,
        GradientCommand::Vectorize(a) => {
            atomic::check_output_path(&a.output, "-o")?;
            let volume = nrrd::load(&a.input)?;
            if let Some(mask) = &a.mask {
                if a.detail {
                    return Err(Error::invalid(
                        "--detail",
                        "is not available with --mask (region solids have no detail channels)",
                    )
                    .into());
                }
                return vectorize_with_mask(&a, &volume, mask, quiet);
            }
            let start = Instant::now();
            let mut solid = vectorize::vectorize(&volume)?;
            if a.optimize {
                vectorize::optimize(&mut solid, &volume, a.iterations as usize);
            }
            if a.detail {
                solid = detail::with_detail(&solid, &volume)?;
            }
            let fit_s = start.elapsed().as_secs_f64();
            let bytes = format::to_bytes(&solid, a.encoding);
            // The error of what is stored: decode the file's own bytes and render them.
            let stored = format::from_bytes(&bytes, "encoded solid")?;
            let rendered = vectorize::render(&stored, [volume.nx, volume.ny, volume.nz]);
            let rms = vectorize::rms(&rendered, &volume);
            let fraction = bytes.len() as f64 / volume.data.len() as f64;
            atomic::write_file(&a.output, &bytes)?;
            if a.json {
                print_summary(&VectorizeSummary {
                    output: &a.output,
                    grid: solid.dims,
                    split_points: None,
                    rms,
                    rms_antialiased: None,
                    rms_without_regions: None,
                    seconds: fit_s,
                    bytes: bytes.len(),
                    fraction_of_volume: fraction,
                });
            } else if !quiet {
                eprintln!(
                    "vectorized {}x{}x{} into a {:?} control grid in {fit_s:.2} s: RMS error {rms:.2}, \
                     {} bytes ({:.1}% of the volume) -> {}",
                    volume.nx,
                    volume.ny,
                    volume.nz,
                    solid.dims,
                    bytes.len(),
                    fraction * 100.0,
                    a.output.display()
                );
            }
        }
        GradientCommand::Edit(a) => {
            atomic::check_output_path(&a.output, "-o")?;
            let mut solid = load(&a.input)?;
            if solid.detail > 0 {
                return Err(Error::invalid(
                    a.input.display().to_string(),
                    "has detail channels; editing takes solids without them (vectorize without \
                     --detail)",
                )
                .into());
            }
            let text = std::fs::read_to_string(&a.strokes).map_err(|e| Error::io(&a.strokes, e))?;
            let strokes = edit::parse_strokes(&text, &a.strokes.display().to_string())?;
            let reference: Vec<f64> = a
                .color
                .split(',')
                .map(|t| t.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .ok()
                .filter(|v: &Vec<f64>| v.iter().all(|x| x.is_finite()))
                .ok_or_else(|| {
                    Error::invalid(
                        format!("--color {}", a.color),
                        "expected numbers like 255,0,0",
                    )
                })?;
            let start = Instant::now();
            let propagation = edit::Propagation {
                alpha: a.alpha,
                beta: a.beta,
            };
            let residual = edit::edit(&mut solid, &strokes, &reference, propagation)?;
            let seconds = start.elapsed().as_secs_f64();
            atomic::write_file(&a.output, &format::to_bytes(&solid, a.encoding))?;
            if a.json {
                print_summary(&EditSummary {
                    output: &a.output,
                    strokes: strokes.len(),
                    seconds,
                    strength_fit_rms: residual,
                    control_points: solid.data.len() / (solid.channels as usize * 4),
                });
            } else if !quiet {
                eprintln!(
                    "edited {} control points with {} strokes in {seconds:.3} s (strength fit RMS \
                     {residual:.3}) -> {}",
                    solid.data.len() / (solid.channels as usize * 4),
                    strokes.len(),
                    a.output.display()
                );
            }
        }
        GradientCommand::Render(a) => {
            atomic::check_output_path(&a.output, "-o")?;
            // A volume's format is known (or refused) before anything is read.
            let output = match a.normal {
                None => crate::io::volume_file::VolumeOutput::resolve(
                    &a.output,
                    "-o",
                    a.format,
                    Default::default(),
                )?,
                Some(_) => crate::io::volume_file::VolumeOutput {
                    format: crate::io::volume_file::VolumeFormat::Png,
                    texture: Default::default(),
                    vdb: Default::default(),
                },
            };
            let solid = GradientFile::load(&a.input)?;
            if let Some(normal) = &a.normal {
                return render_slice(&a, &solid, normal, quiet);
            }
            let n = a.size.map(|s| [s; 3]).unwrap_or_else(|| solid.extent());
            if n.iter().any(|&s| s > 2048) {
                return Err(Error::invalid(
                    format!("--size {}", n[0]),
                    "a volume side is at most 2048",
                )
                .into());
            }
            output.check(&a.output, n)?;
            solid.check_render_memory(n)?;
            let compute = a.backend.open()?;
            let start = Instant::now();
            let query = Query::volume(n);
            let mut v = crate::volume::Volume::new(n[0], n[1], n[2], solid.channels());
            v.data = solid.eval_u8(&query, &compute, blend_of(&a), !a.no_detail)?;
            crate::io::volume_file::save(&v, &a.output, output)?;
            if a.json {
                print_summary(&RenderSummary {
                    output: &a.output,
                    size: n,
                    channels: v.channels,
                    seconds: start.elapsed().as_secs_f64(),
                    backend: compute.describe(),
                });
            } else if !quiet {
                eprintln!(
                    "rendered {}x{}x{} in {:.2} s ({}) -> {}",
                    n[0],
                    n[1],
                    n[2],
                    start.elapsed().as_secs_f64(),
                    compute.describe(),
                    a.output.display()
                );
            }
        }
    }
    Ok(())
}

/// `gradient synth --json`.
#[derive(serde::Serialize)]
struct GradientSynthSummary<'a> {
    output: &'a Path,
    grid: [u32; 3],
    period: u32,
    seconds: f64,
    bytes: usize,
    fraction_of_volume: f64,
    levels: Vec<GradientLevelSummary>,
    optimize_seconds: f64,
    optimize_rms: [f64; 2],
    regions: Option<&'a crate::gradient::synth::RegionReport>,
    backend: String,
    peak_rss_bytes: Option<u64>,
}

#[derive(serde::Serialize)]
struct GradientLevelSummary {
    spacing: u32,
    size: u32,
    candidates: usize,
    pca_energy: f64,
    prepare_seconds: f64,
    match_seconds: f64,
    update_seconds: f64,
    refitted: f64,
}

/// `gradient vectorize --json` (the region fields with `--mask` only).
#[derive(serde::Serialize)]
struct VectorizeSummary<'a> {
    output: &'a Path,
    grid: [u32; 3],
    #[serde(skip_serializing_if = "Option::is_none")]
    split_points: Option<usize>,
    rms: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_antialiased: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_without_regions: Option<f64>,
    seconds: f64,
    bytes: usize,
    fraction_of_volume: f64,
}

/// `gradient edit --json`.
#[derive(serde::Serialize)]
struct EditSummary<'a> {
    output: &'a Path,
    strokes: usize,
    seconds: f64,
    strength_fit_rms: f64,
    control_points: usize,
}

/// `gradient render --json` (a volume).
#[derive(serde::Serialize)]
struct RenderSummary<'a> {
    output: &'a Path,
    size: [u32; 3],
    channels: u32,
    seconds: f64,
    backend: String,
}
