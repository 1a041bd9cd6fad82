//! `solidsynth lapped`: lapped solid textures: fill a mesh with pasted solid exemplars, then
//! cut, render or bake the model.

use super::cut::triple;
use super::output::print_summary;
use super::{progress_bar, BackendArgs};
use crate::backend::{BackendChoice, Compute};
use crate::io::{atomic, nrrd};
use crate::lapped::camera::Camera;
use crate::lapped::exemplar::SolidExemplar;
use crate::lapped::field::Constraints;
use crate::lapped::model::LstModel;
use crate::lapped::{self, FillOptions};
use crate::lazy::cut::CutSpec;
use crate::mesh::{self, bake as mesh_bake};
use crate::Error;
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum LappedCommand {
    /// Tetrahedralize a closed mesh and fill it with patches of a solid exemplar (.lst model).
    #[command(after_help = super::help::LAPPED_FILL)]
    Fill(FillArgs),
    /// A planar cross-section of a model as a PNG.
    #[command(after_help = super::help::LAPPED_CUT)]
    Cut(CutArgs),
    /// An offscreen GPU render of a model's surface as a PNG.
    #[command(after_help = super::help::LAPPED_RENDER)]
    Render(RenderArgs),
    /// The model's surface as a textured binary glTF (.glb).
    #[command(after_help = super::help::LAPPED_BAKE)]
    Bake(BakeArgs),
    /// Write a procedural depth-varying exemplar (texture y = depth) as NRRD, for the kiwi
    /// example (types 1-b and 2-b).
    #[command(after_help = super::help::LAPPED_EXEMPLAR)]
    Exemplar(ExemplarArgs),
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Exemplar")]
pub struct ExemplarArgs {
    /// The procedural exemplar: `kiwi`, the one there is.
    #[arg(long, default_value = "kiwi")]
    pub kind: String,
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(8..=256))]
    pub size: u32,
    /// The exemplar volume; the extension picks the format, as `synth -o` (`lapped fill` reads
    /// NRRD).
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// The output's format, whatever its extension.
    #[arg(help_heading = "Output", long, value_enum)]
    pub format: Option<crate::io::volume_file::VolumeFormat>,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Fill")]
pub struct FillArgs {
    /// Closed (or nearly closed) triangle mesh: .obj, .ply, .ply.gz, .glb or .gltf, or a built-in
    /// shape: `builtin:sphere` (unit sphere) or `builtin:bent-cylinder` (radius 0.3 around a
    /// quarter circle of radius 1 from (1,0,0) to (0,1,0)).
    #[arg(long)]
    pub mesh: PathBuf,
    /// Solid exemplar: a cubic NRRD volume (e.g. from `solidsynth synth --tileable --size 64`).
    #[arg(long)]
    pub exemplar: PathBuf,
    /// Constraints file (JSON: texture type, scales, strokes, depth). Default: type 0, isotropic.
    #[arg(long)]
    pub field: Option<PathBuf>,
    /// World size of one exemplar cube (default: a third of the mesh's longest side; the
    /// constraints file's "scale" wins over this).
    #[arg(long)]
    pub scale: Option<f64>,
    /// Tet lattice cells along the mesh's longest side (12 gives ~5,000 tets for a bunny).
    #[arg(long, default_value_t = lapped::DEFAULT_RESOLUTION)]
    pub resolution: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output model (.lst).
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Cut")]
pub struct CutArgs {
    /// The model (.lst).
    pub model: PathBuf,
    /// A point of the cut plane (the image centre), X,Y,Z in model units, or `center` (of the
    /// model's bounding box).
    #[arg(long, allow_hyphen_values = true)]
    pub origin: String,
    /// Normal of the plane, NX,NY,NZ (any length but zero).
    #[arg(long, allow_hyphen_values = true)]
    pub normal: String,
    /// Up direction, projected onto the plane (default +y, or +z when the normal is along y).
    #[arg(long, allow_hyphen_values = true)]
    pub up: Option<String>,
    /// Pixels per side.
    #[arg(long, default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(1..=crate::lazy::cut::MAX_CUT_SIZE as i64))]
    pub size: u32,
    /// Model units across the image (default: the model's bounding-box diagonal).
    #[arg(long)]
    pub extent: Option<f64>,
    /// Cut K times and print the median and p95 latency of all but the first cut.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=10000))]
    pub repeat: u32,
    /// Output: the cut as a PNG (pixels off the model transparent).
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Camera")]
pub struct RenderArgs {
    /// The model (.lst).
    pub model: PathBuf,
    /// Orbit camera: AZ,EL[,DIST]: azimuth about +y from +z and elevation (degrees), distance
    /// in bounding radii (default 2.6).
    #[arg(
        help_heading = "Camera",
        long,
        default_value = "30,20",
        allow_hyphen_values = true
    )]
    pub camera: String,
    /// Pixels per side.
    #[arg(help_heading = "Camera", long, default_value_t = 1024)]
    pub size: u32,
    #[command(flatten)]
    pub backend: BackendArgs,
    /// Output: the render as a PNG (background transparent).
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Bake")]
pub struct BakeArgs {
    /// The model (.lst).
    pub model: PathBuf,
    /// Texels per triangle cell side (default: about one per exemplar voxel).
    #[arg(long, value_parser = super::whole_number_in::<2, 256>)]
    pub texels: Option<u32>,
    /// Output: .glb.
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

pub fn run(cmd: LappedCommand, quiet: bool) -> anyhow::Result<()> {
    match cmd {
        LappedCommand::Fill(a) => fill(a, quiet),
        LappedCommand::Cut(a) => cut(a, quiet),
        LappedCommand::Render(a) => render(a, quiet),
        LappedCommand::Bake(a) => bake(a, quiet),
        LappedCommand::Exemplar(a) => {
            atomic::check_output_path(&a.output, "-o")?;
            if a.kind != "kiwi" {
                return Err(Error::invalid(
                    format!("--kind {}", a.kind),
                    "the only procedural exemplar is `kiwi`",
                )
                .into());
            }
            let output = crate::io::volume_file::VolumeOutput::resolve(
                &a.output,
                "-o",
                a.format,
                Default::default(),
            )?;
            let volume = lapped::exemplar::kiwi(a.size).to_volume();
            crate::io::volume_file::save(&volume, &a.output, output)?;
            if a.json {
                print_summary(&ExemplarSummary {
                    output: &a.output,
                    kind: &a.kind,
                    size: [volume.nx, volume.ny, volume.nz],
                    channels: volume.channels,
                });
            }
            Ok(())
        }
    }
}

fn fill(args: FillArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&args.output, "-o")?;
    atomic::check_output_extension(&args.output, "-o", "a lapped model", &["lst"])?;
    let mesh_name = args.mesh.display().to_string();
    let surface = load_mesh(&args.mesh)?;
    let exemplar_name = args.exemplar.display().to_string();
    let volume = nrrd::load(&args.exemplar)?;
    let exemplar = SolidExemplar::from_volume(&volume, &exemplar_name)?;
    let (constraints, constraints_name) = match &args.field {
        Some(p) => (Constraints::load(p)?, p.display().to_string()),
        None => (Constraints::isotropic(), "--field".to_string()),
    };
    let opts = FillOptions {
        resolution: args.resolution,
        scale: args.scale,
        seed: args.seed,
    };
    let bar = progress_bar(quiet || args.json);
    let report_progress = |covered: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(covered as u64);
        bar.set_message(format!("{covered}/{total} tets covered"));
    };
    let start = Instant::now();
    let (model, report) = lapped::build(
        lapped::FillInputs {
            mesh: &surface,
            mesh_name: &mesh_name,
            exemplar,
            exemplar_source: &exemplar_name,
            constraints: &constraints,
            constraints_name: &constraints_name,
        },
        &opts,
        &report_progress,
    )?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let bytes = model.to_bytes();
    atomic::write_file(&args.output, &bytes)?;
    let q = &report.quality;
    if args.json {
        print_summary(&FillSummary {
            output: &args.output,
            texture_type: model.kind.name(),
            tets: q.tets,
            vertices: q.vertices,
            min_dihedral_degrees: q.min_dihedral,
            max_dihedral_degrees: q.max_dihedral,
            inverted_tets: q.inverted,
            volume: q.volume,
            patches: report.fill.patches,
            forced_tets: report.fill.forced,
            mean_layers_per_tet: model.mean_layers(),
            mean_clump_tets: report.fill.mean_clump_tets,
            default_scale: report.default_scale,
            mesh_seconds: report.mesh_seconds,
            field_seconds: report.field_seconds,
            fill_seconds: report.fill_seconds,
            total_seconds: seconds,
            model_bytes: bytes.len(),
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
        });
    } else if !quiet {
        if report.fill.forced > 0 {
            eprintln!(
                "warning: {} tets never reached full coverage (too large for the patch scale): \
                 raise --scale or --resolution",
                report.fill.forced
            );
        }
        eprintln!(
            "tet mesh: {} tets, {} vertices, dihedral angles {:.1}..{:.1} degrees, {} inverted \
             ({:.2} s)\nfilled with {} patches (type {}, {:.1} layers per tet, {} tets forced) in \
             {:.2} s; field {:.2} s; total {seconds:.2} s -> {} ({:.1} MiB)",
            q.tets,
            q.vertices,
            q.min_dihedral,
            q.max_dihedral,
            q.inverted,
            report.mesh_seconds,
            report.fill.patches,
            model.kind.name(),
            model.mean_layers(),
            report.fill.forced,
            report.fill_seconds,
            report.field_seconds,
            args.output.display(),
            bytes.len() as f64 / (1 << 20) as f64
        );
    }
    Ok(())
}

/// A mesh file or a `builtin:` shape.
fn load_mesh(path: &std::path::Path) -> crate::Result<mesh::Mesh> {
    match path.to_str() {
        Some("builtin:sphere") => Ok(lapped::shapes::sphere(48, 24)),
        Some("builtin:bent-cylinder") => Ok(lapped::shapes::bent_cylinder(0.3, 1.0, 32, 32)),
        Some(other) if other.starts_with("builtin:") => Err(Error::invalid(
            format!("--mesh {other}"),
            "unknown built-in shape (builtin:sphere, builtin:bent-cylinder)",
        )),
        _ => mesh::load(path),
    }
}

fn cut(args: CutArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_png_output(&args.output, "-o")?;
    let model = LstModel::load(&args.model)?;
    let (lo, hi) = model.mesh.vertices.iter().fold(
        (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    let extent = args.extent.unwrap_or((hi - lo).length());
    // Without --extent, the model's size is what is wrong.
    let shown = crate::util::number_text(extent);
    let what = match args.extent {
        Some(_) => format!("--extent {shown}"),
        None => format!(
            "{} (its bounding-box diagonal, {shown}, is the default --extent)",
            args.model.display()
        ),
    };
    if !(extent.is_finite() && extent > 0.0) {
        return Err(Error::invalid(what, "must be a positive number").into());
    }
    let spacing = extent / args.size as f64;
    let max_spacing = crate::lazy::cut::MAX_CUT_SPACING;
    if spacing > max_spacing {
        return Err(Error::invalid(
            what,
            format!(
                "over --size {} is {} world units a pixel; at most {max_spacing}",
                args.size,
                crate::util::number_text(spacing)
            ),
        )
        .into());
    }
    let spec = CutSpec {
        origin: if args.origin == "center" {
            ((lo + hi) / 2.0).to_array()
        } else {
            triple(&args.origin, "--origin")?
        },
        normal: triple(&args.normal, "--normal")?,
        up: args.up.as_deref().map(|u| triple(u, "--up")).transpose()?,
        size: args.size,
        spacing,
    };
    spec.frame()?;
    let mut latencies = Vec::new();
    let mut image = None;
    for _ in 0..args.repeat {
        let start = Instant::now();
        image = Some(lapped::cut::cut(&model, &spec)?);
        latencies.push(start.elapsed().as_secs_f64() * 1000.0);
    }
    let image = image.expect("repeat >= 1");
    atomic::save_png(&args.output, &image)?;
    let times = super::output::Latencies::of(&latencies);
    let (median, p95) = (times.median_ms, times.p95_ms);
    let inside = image.pixels().filter(|p| p[3] > 0).count();
    if args.json {
        print_summary(&LappedCutSummary {
            output: &args.output,
            size: args.size,
            repeat: args.repeat,
            latencies: times,
            pixels_inside: inside,
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
        });
    } else if !quiet {
        eprintln!(
            "cut {0}x{0} ({inside} pixels inside the model) -> {1}: median {median:.2} ms, p95 \
             {p95:.2} ms {2}",
            args.size,
            args.output.display(),
            super::output::Latencies::over(args.repeat)
        );
    }
    Ok(())
}

fn render(args: RenderArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_png_output(&args.output, "-o")?;
    let model = LstModel::load(&args.model)?;
    let camera = Camera::orbit(&model, &args.camera)?;
    if args.backend.backend == BackendChoice::Cpu {
        return Err(Error::invalid(
            "--backend cpu",
            "rendering needs a GPU adapter (lavapipe works); use `lapped cut` or `lapped bake` \
             without one",
        )
        .into());
    }
    let mut backend = args.backend.clone();
    // `auto` means the CPU backend on machines with only lavapipe; the render needs wgpu.
    backend.backend = BackendChoice::Gpu;
    let compute = backend.open()?;
    let Compute::Gpu(gpu) = &compute else {
        unreachable!("--backend gpu opens a GPU")
    };
    let start = Instant::now();
    let image = compute.lapped_render(&model.render_scene(), &camera, args.size)?;
    let ms = start.elapsed().as_secs_f64() * 1000.0;
    atomic::save_png(&args.output, &image)?;
    if args.json {
        print_summary(&LappedRenderSummary {
            output: &args.output,
            size: args.size,
            render_ms: ms,
            adapter: gpu.describe(),
        });
    } else if !quiet {
        eprintln!(
            "rendered {0}x{0} in {ms:.1} ms on {1} -> {2}",
            args.size,
            gpu.describe(),
            args.output.display()
        );
    }
    Ok(())
}

fn bake(args: BakeArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&args.output, "-o")?;
    atomic::check_output_extension(&args.output, "-o", "a glTF binary", &["glb"])?;
    let model = LstModel::load(&args.model)?;
    let start = Instant::now();
    let (surface, tets) = lapped::bake::surface(&model);
    // The scale a patch was pasted at is in its texture coordinates: one texture unit spans
    // |grad w|^-1 model units. Estimate it from the first layer of the first surface tet.
    let scale = layer_scale(&model, tets[0] as usize);
    let texels = match args.texels {
        Some(texels) => texels,
        None => lapped::bake::auto_texels(&surface, &model, scale)?,
    };
    let atlas = mesh_bake::Atlas::new(surface.triangles.len(), texels, 0)?;
    let image = lapped::bake::bake(&model, &surface, &tets, &atlas)?;
    let png = atomic::png_bytes(&image)?;
    drop(image);
    atomic::write_with(&args.output, |f| {
        mesh::glb::write_glb(f, &surface, &atlas, &png)
    })?;
    let seconds = start.elapsed().as_secs_f64();
    if args.json {
        print_summary(&BakeSummary {
            output: &args.output,
            triangles: surface.triangles.len(),
            texels,
            atlas: [atlas.width, atlas.height],
            seconds,
        });
    } else if !quiet {
        eprintln!(
            "baked {} surface triangles into a {}x{} atlas ({texels} texels per cell) in \
             {seconds:.2} s -> {}",
            surface.triangles.len(),
            atlas.width,
            atlas.height,
            args.output.display()
        );
    }
    Ok(())
}

/// Model units per texture unit of the first layer of tet `t` (the mean stretch of the affine
/// map from the tet to texture space).
fn layer_scale(model: &LstModel, t: usize) -> f64 {
    let Some(layer) = model.layers[t].first() else {
        return 1.0;
    };
    let p = model.mesh.corners(t);
    let w = layer.coords.map(|c| glam::Vec3::from_array(c).as_dvec3());
    let (mut world, mut texture) = (0.0, 0.0);
    for a in 0..4 {
        for b in a + 1..4 {
            world += (p[b] - p[a]).length();
            texture += (w[b] - w[a]).length();
        }
    }
    if texture > 0.0 {
        world / texture
    } else {
        1.0
    }
}

/// `lapped fill --json`.
#[derive(serde::Serialize)]
struct FillSummary<'a> {
    output: &'a Path,
    texture_type: &'static str,
    tets: usize,
    vertices: usize,
    min_dihedral_degrees: f64,
    max_dihedral_degrees: f64,
    inverted_tets: usize,
    volume: f64,
    patches: usize,
    forced_tets: usize,
    mean_layers_per_tet: f64,
    mean_clump_tets: f64,
    default_scale: f64,
    mesh_seconds: f64,
    field_seconds: f64,
    fill_seconds: f64,
    total_seconds: f64,
    model_bytes: usize,
    peak_rss_bytes: Option<u64>,
}

/// `lapped cut --json`.
#[derive(serde::Serialize)]
struct LappedCutSummary<'a> {
    output: &'a Path,
    size: u32,
    repeat: u32,
    #[serde(flatten)]
    latencies: super::output::Latencies,
    pixels_inside: usize,
    peak_rss_bytes: Option<u64>,
}

/// `lapped render --json`.
#[derive(serde::Serialize)]
struct LappedRenderSummary<'a> {
    output: &'a Path,
    size: u32,
    render_ms: f64,
    adapter: String,
}

/// `lapped bake --json`.
#[derive(serde::Serialize)]
struct BakeSummary<'a> {
    output: &'a Path,
    triangles: usize,
    texels: u32,
    atlas: [u32; 2],
    seconds: f64,
}

/// `lapped exemplar --json`.
#[derive(serde::Serialize)]
struct ExemplarSummary<'a> {
    output: &'a Path,
    kind: &'a str,
    size: [u32; 3],
    channels: u32,
}
