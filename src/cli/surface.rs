//! `solidsynth surface`: the solid baked onto a mesh surface (binary glTF, or OBJ + MTL + PNG).

use super::analyze::open_and_analyze;
use super::synth::SolidParams;
use crate::io::atomic;
use crate::mesh::{self, bake};
use crate::solid::surface::{AtlasLayout, SurfacePlan};
use crate::Error;
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug)]
#[command(next_help_heading = "Surface")]
pub struct SurfaceArgs {
    #[command(flatten)]
    pub solid: SolidParams,
    /// Mesh (.obj, .ply, .ply.gz, .glb or .gltf); open or non-manifold meshes are fine.
    #[arg(help_heading = "Surface", long)]
    pub mesh: PathBuf,
    /// The mesh is scaled so its longest side spans this many finest-level voxels.
    #[arg(help_heading = "Surface", long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=crate::solid::limits::MAX_SURFACE_RESOLUTION as i64))]
    pub resolution: u32,
    /// Voxels per texel step along a triangle's edges: each triangle's atlas cell is sized to
    /// the triangle (default 1, grown only when the atlas would not fit 16384^2 or memory).
    #[arg(help_heading = "Surface", long, conflicts_with = "texels")]
    pub texel_size: Option<f64>,
    /// Instead of cells sized to their triangles, the same square cell of T x T texels for every
    /// triangle (2..=256).
    #[arg(help_heading = "Surface", long, value_parser = super::whole_number_in::<2, 256>)]
    pub texels: Option<u32>,
    /// The texture layout: `packed` (an atlas of its own: every triangle a cell, any mesh) or
    /// `own` (the mesh's own texture coordinates, as Blender's and Substance's bakers use them:
    /// texels outside every triangle dilated; overlapping or missing UVs are refused).
    #[arg(help_heading = "Surface", long, value_enum, default_value_t = UvLayout::Packed)]
    pub uv: UvLayout,
    /// With `--uv own`: the texture's side in texels (default: the power of two giving about
    /// one texel per voxel).
    #[arg(help_heading = "Surface", long, conflicts_with_all = ["texels", "texel_size"],
          value_parser = super::whole_number_in::<1, { crate::mesh::bake::MAX_ATLAS_SIDE }>)]
    pub texture_size: Option<u32>,
    /// Mip levels the packed atlas keeps apart: each cell gets a gutter of 2^K texels filled by
    /// dilation, and the .glb asks for mipmapped filtering (0..=6; 0: no gutter, and the .glb is
    /// sampled without mipmaps).
    #[arg(help_heading = "Surface", long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=6))]
    pub mips: u32,
    /// Output: .glb (texture embedded) or .obj (writes .mtl and .png beside it).
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
}

/// `--uv`: where the bake's texture coordinates come from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum UvLayout {
    Packed,
    Own,
}

/// The files an output path stands for: (main, Some((mtl, png)) for OBJ).
fn outputs(path: &Path) -> crate::Result<Option<(PathBuf, PathBuf)>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("glb") => Ok(None),
        Some("obj") => {
            // The OBJ names its .mtl, and the .mtl its .png, by file name on a line of
            // whitespace-separated words: a name with a space would be read as two.
            let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
            if stem
                .as_deref()
                .is_some_and(|s| s.chars().any(char::is_whitespace))
            {
                return Err(Error::invalid(
                    format!("-o {}", path.display()),
                    "an .obj output's name may not contain spaces: the .obj and .mtl refer to \
                     its .mtl and .png by name, and OBJ readers split names at spaces",
                ));
            }
            Ok(Some((
                path.with_extension("mtl"),
                path.with_extension("png"),
            )))
        }
        _ => Err(Error::invalid(
            format!("-o {}", path.display()),
            "the output must end in .glb or .obj",
        )),
    }
}

pub fn run(args: SurfaceArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&args.output, "-o")?;
    let extra = outputs(&args.output)?;
    if let Some((mtl, png)) = &extra {
        atomic::check_derived_output_path(mtl, "-o (its .mtl)")?;
        atomic::check_derived_output_path(png, "-o (its .png)")?;
    }
    let params = args.solid.synth_params();
    params.validate()?;
    let mesh = mesh::load(&args.mesh)?;
    let gutter = AtlasLayout::gutter_for_mips(args.mips);
    let layout = match (args.uv, args.texels) {
        (UvLayout::Own, _) => {
            if args.texels.is_some() || args.texel_size.is_some() || args.mips > 0 {
                return Err(Error::invalid(
                    "--uv own",
                    "lays texels out by the mesh's texture coordinates: --texels, --texel-size \
                     and --mips apply to the packed atlas (use --texture-size)",
                )
                .into());
            }
            AtlasLayout::MeshUvs {
                texture_size: args.texture_size,
            }
        }
        (UvLayout::Packed, Some(texels)) => AtlasLayout::Texels { texels, gutter },
        (UvLayout::Packed, None) => AtlasLayout::TexelSize {
            size: args.texel_size,
            gutter,
        },
    };
    if args.uv == UvLayout::Packed && args.texture_size.is_some() {
        return Err(Error::invalid(
            "--texture-size",
            "applies to --uv own (the packed atlas is sized by --texel-size or --texels)",
        )
        .into());
    }
    // Planned (atlas, memory) before the analysis: a bake that cannot fit is refused at once.
    let plan = SurfacePlan::new(
        &mesh,
        &args.mesh.display().to_string(),
        args.resolution,
        layout,
        args.solid.coarse_cache,
        args.solid.planned_group(),
    )?;
    let (atlas, place) = (&plan.atlas, &plan.placement);
    let start = Instant::now();
    // The analysis (loaded or computed) is not part of the surface's time.
    let analysis_start = Instant::now();
    let (compute, analysis) = open_and_analyze(&args.solid.input, quiet || args.json)?;
    let analysis_time = analysis_start.elapsed();
    let bar = super::progress_bar(quiet || args.json);
    let shown = bar.clone();
    let report: crate::solid::ProgressFn = std::sync::Arc::new(move |m: &str, f: f32| {
        shown.report(m, f);
    });
    let mut solid = args.solid.solid(&analysis, &compute, false, Some(report))?;
    // The solid keeps what it reads: the analysis (10 MiB for the built-in exemplar) is not
    // held through the synthesis.
    drop(analysis);
    let baked = solid.bake_surface(&mesh, &plan)?;
    // Of the solid, baking needs only these: its level data and tables (on a GPU, its
    // buffers) are freed before the atlas's PNG is made.
    let stats = solid.last_stats().cloned().unwrap_or_default();
    drop(solid);
    bar.finish_and_clear();
    let seconds = (start.elapsed() - analysis_time).as_secs_f64();
    let png = baked.png()?;
    drop(baked);
    match &extra {
        None => atomic::write_with(&args.output, |f| {
            mesh::glb::write_glb(f, &mesh, atlas, &png)
        })?,
        Some((mtl, png_path)) => {
            // The three files appear together or not at all.
            let name = |p: &Path| p.file_name().unwrap().to_string_lossy().into_owned();
            let mut outputs = atomic::Outputs::new();
            outputs.write_file(png_path, &png)?;
            outputs.write_file(mtl, bake::mtl_text(&name(png_path)).as_bytes())?;
            outputs.write_file(
                &args.output,
                bake::obj_text(&mesh, atlas, &name(mtl))?.as_bytes(),
            )?;
            outputs.commit()?;
        }
    }
    let finest = stats.voxels_per_level.last().copied().unwrap_or(0);
    let fraction = finest as f64 / (args.resolution as f64).powi(3);
    if args.json {
        super::output::print_summary(&SurfaceSummary {
            output: &args.output,
            triangles: mesh.triangles.len(),
            resolution: args.resolution,
            texels: args.texels,
            texel_size: plan.texel_size,
            uv: args.uv,
            gutter: atlas.gutter,
            mip_safe: atlas.mip_safe(),
            atlas: [atlas.width, atlas.height],
            max_texel_step_voxels: atlas.max_texel_step(&mesh, place),
            placement: PlacementSummary::of(&mesh, place),
            synthesis_seconds: seconds,
            stats: &stats,
            finest_fraction_of_volume: fraction,
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
            backend: compute.describe(),
        });
    } else if !quiet {
        eprintln!(
            "surface of {} triangles at {}^3: atlas {}x{} ({}, longest texel step {:.2} \
             voxels) in {seconds:.2} s; \
             finest voxels synthesized {finest} ({:.3}% of the volume), per level {:?}, peak state \
             {:.1} MiB -> {}",
            mesh.triangles.len(),
            args.resolution,
            atlas.width,
            atlas.height,
            plan.layout,
            atlas.max_texel_step(&mesh, place),
            fraction * 100.0,
            stats.voxels_per_level,
            stats.peak_state_bytes as f64 / (1 << 20) as f64,
            args.output.display()
        );
    }
    Ok(())
}

/// `surface --json`.
#[derive(serde::Serialize)]
struct SurfaceSummary<'a> {
    output: &'a Path,
    triangles: usize,
    resolution: u32,
    texels: Option<u32>,
    texel_size: Option<f64>,
    /// `--uv`.
    uv: UvLayout,
    /// Texels of dilated room around each packed cell.
    gutter: u32,
    /// Whether the .glb's sampler uses mipmaps.
    mip_safe: bool,
    atlas: [u32; 2],
    max_texel_step_voxels: f64,
    /// Where the mesh lies in the solid: `region --box` with `voxel_box` gives the volume the
    /// surface was cut from.
    placement: PlacementSummary,
    synthesis_seconds: f64,
    stats: &'a crate::lazy::SynthStats,
    finest_fraction_of_volume: f64,
    peak_rss_bytes: Option<u64>,
    backend: String,
}

/// The mesh-to-voxel transform of a bake: voxel = (vertex - origin) * scale.
#[derive(serde::Serialize)]
struct PlacementSummary {
    /// Mesh coordinates that land on voxel (0, 0, 0).
    origin: [f64; 3],
    /// Voxels per mesh unit.
    scale: f64,
    /// The half-open voxel box [lo, hi) holding the mesh, as `region --box` takes it.
    voxel_box: [[i64; 3]; 2],
}

impl PlacementSummary {
    fn of(mesh: &crate::mesh::Mesh, place: &crate::mesh::Placement) -> PlacementSummary {
        let (lo, hi) = mesh.bounds();
        let (lo, hi) = (
            place.to_voxels(lo.as_vec3().to_array()),
            place.to_voxels(hi.as_vec3().to_array()),
        );
        PlacementSummary {
            origin: place.origin.into(),
            scale: place.scale,
            voxel_box: [
                [lo.x, lo.y, lo.z].map(|c| c.floor() as i64),
                [hi.x, hi.y, hi.z].map(|c| c.floor() as i64 + 1),
            ],
        }
    }
}
