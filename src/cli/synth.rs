//! `solidsynth synth`: a full volume, the box [0, N)^3 of the infinite solid.

use super::analyze::{open_and_analyze, InputArgs};
use super::output::{print_summary, KernelTime};
use crate::io::atomic;
use crate::io::volume_file::{VolumeOutput, VolumeWriter};
use crate::lazy::{Box3, CandidateMode, ColorSource, SynthOptions, SynthParams};
use crate::metrics::sheet::contact_sheet;
use crate::solid::limits;
use crate::volume::Volume;
use crate::Error;
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Edge of the cube [0, N)^3 to synthesize, in finest-level voxels.
    #[arg(long, value_parser = super::whole_number_in::<8, { limits::MAX_BOX_SIDE }>)]
    pub size: u32,
    /// A periodic solid of period N (copies of the volume tile space seamlessly): its own
    /// deterministic solid, not the box [0, N)^3 of the infinite one. N a multiple of 32.
    #[arg(long)]
    pub tileable: bool,
    #[command(flatten)]
    pub solid: SolidArgs,
}

/// `solidsynth region`: any box of the infinite solid.
#[derive(Args, Debug)]
pub struct RegionArgs {
    /// Half-open box X0,Y0,Z0,X1,Y1,Z1 in finest-level voxels (negative coordinates allowed):
    /// `synth --size N` is `region --box 0,0,0,N,N,N`.
    #[arg(
        long = "box",
        value_name = "X0,Y0,Z0,X1,Y1,Z1",
        allow_hyphen_values = true
    )]
    pub region: String,
    #[command(flatten)]
    pub solid: SolidArgs,
    #[command(flatten)]
    pub zarr: super::region_zarr::ZarrArgs,
}

/// What defines the solid: shared by `synth`, `region` and `cut`.
#[derive(Args, Debug)]
#[command(next_help_heading = "Solid")]
pub struct SolidParams {
    #[command(flatten)]
    pub input: InputArgs,
    /// Seed of the jitter field and the tiling offsets.
    #[arg(help_heading = "Solid", long, default_value_t = 0)]
    pub seed: u64,
    /// Jitter magnitude (0 disables the warp).
    #[arg(
        help_heading = "Solid",
        long,
        default_value_t = 1.0,
        allow_hyphen_values = true
    )]
    pub jitter: f32,
    /// Candidates searched by the correction: the paper's 3D candidates, or 2D (ablation).
    #[arg(help_heading = "Solid", long, value_enum, default_value = "3d")]
    pub candidates: CandidateMode,
    /// Correction passes per level: one count for every level, or one per level, coarsest
    /// first (`2,2,2,1`).
    #[arg(
        help_heading = "Solid",
        long,
        default_value = "2",
        value_name = "N|N,N,N,N"
    )]
    pub passes: crate::lazy::PassSchedule,
    /// Output colour: the mean of the voxel's three exemplar pixels (the paper's rule);
    /// `fitted`: those pixels weighted by how well each plane's 5x5 neighbourhood fits its
    /// exemplar there (closer to the exemplar on most quality measures; a voxel's colour then
    /// reads its neighbours, so requests compute 2 voxels more around their output); `matched`:
    /// the mean with the exemplar's mean colour and contrast restored (a table from
    /// a probe solid synthesized when the command starts; better histogram and sharpness
    /// scores); or one exemplar's pixel (x, y, z). Or one of these per colour channel, red
    /// first, separated by commas (`x,y,z`: red from Ex, green from Ey, blue from Ez).
    #[arg(
        help_heading = "Solid",
        long,
        default_value = "average",
        value_name = "SOURCE[,SOURCE...]"
    )]
    pub color: ColorSource,
    /// Coarse-level cache (paper 6.2): the levels above the finest come from one tileable solid
    /// of period N (a multiple of 64), synthesized once and read through the jitter warp; each
    /// request then synthesizes only the finest level. A different solid, as deterministic.
    #[arg(
        help_heading = "Solid",
        long,
        value_name = "N",
        value_parser = parse_coarse_cache,
        allow_hyphen_values = true
    )]
    pub coarse_cache: Option<u32>,
    /// Largest group of the request synthesized at once: a cube of this edge in voxels (a
    /// multiple of 4). Smaller groups bound the working memory of large boxes and surfaces, at
    /// the cost of each group recomputing the finest level's dependency padding (the coarser
    /// levels are synthesized once for all groups, in groups of this edge in their own voxels,
    /// a box's a quarter more: their padding makes them a little larger); the output is
    /// the same whatever the grouping. Default: for boxes and surfaces 128 where the device's
    /// memory is the host's (the CPU backend, lavapipe, an integrated GPU), else 512.
    #[arg(
        long,
        value_name = "VOXELS",
        value_parser = parse_max_group,
        help_heading = "Performance"
    )]
    pub max_group: Option<u32>,
}

impl SolidParams {
    /// The solid of `analysis` with these parameters on `compute` (the library's defaults
    /// otherwise: [`SynthOptions`]), reporting to `progress`.
    pub fn solid(
        &self,
        analysis: &crate::analysis::Analysis,
        compute: &crate::backend::Compute,
        profile: bool,
        progress: Option<crate::solid::ProgressFn>,
    ) -> crate::Result<crate::Solid> {
        let options = SynthOptions {
            max_group: self.max_group,
            profile,
            ..Default::default()
        };
        crate::Solid::new(
            analysis,
            self.synth_params(),
            options,
            compute.clone(),
            progress,
        )
    }

    /// The group edge the memory checks of boxes and surfaces assume, before the backend is
    /// open: [`memory::HOST_MEMORY_GROUP`] for `--backend cpu`, else the largest (a conservative
    /// estimate).
    pub fn planned_group(&self) -> u32 {
        crate::solid::memory::planned_group(self.max_group, self.input.backend.backend)
    }

    pub fn synth_params(&self) -> SynthParams {
        SynthParams {
            seed: self.seed,
            jitter: self.jitter,
            candidates: self.candidates,
            passes: self.passes,
            color: self.color,
            coarse_cache: self.coarse_cache,
        }
    }
}

/// The solid and the volume outputs: shared by `synth` and `region`.
#[derive(Args, Debug)]
#[command(next_help_heading = "Output")]
pub struct SolidArgs {
    #[command(flatten)]
    pub solid: SolidParams,
    /// Output volume; its extension picks the format: .nrrd, .npy (NumPy, shape Z,Y,X,C), .tif
    /// or .tiff (a page per z slice, an ImageJ stack), .ktx2 (a 3D texture), .vdb (OpenVDB
    /// density and color grids), .vti (ParaView), .png (a flipbook of all z slices); with
    /// `region`, .zarr (a chunked Zarr v3 array).
    #[arg(help_heading = "Output", short, long)]
    pub output: PathBuf,
    /// The output's format, whatever its extension (`nrrd-gzip`: NRRD with gzip-compressed
    /// data, as 3D Slicer writes; `.nrrd` alone is written raw, the fastest to write and read).
    #[arg(help_heading = "Output", long, value_enum)]
    pub format: Option<crate::io::volume_file::VolumeFormat>,
    /// KTX2 only: sRGB-encoded colour (the `_SRGB` formats).
    #[arg(help_heading = "Output", long)]
    pub srgb: bool,
    /// KTX2 only: write the full mip chain (2x2x2 box filter).
    #[arg(help_heading = "Output", long)]
    pub mips: bool,
    /// OpenVDB only: the world size of a voxel (the grids are placed at the box's position in
    /// the solid times this).
    #[arg(
        help_heading = "Output",
        long,
        value_name = "SIZE",
        default_value_t = 1.0
    )]
    pub voxel_size: f64,
    /// Also write one PNG per z slice into this (new or empty) directory.
    #[arg(help_heading = "Output", long)]
    pub slices: Option<PathBuf>,
    /// Also write all z slices in one grid PNG (the layout Unity and Unreal import as a 3D texture).
    #[arg(help_heading = "Output", long)]
    pub flipbook: Option<PathBuf>,
    /// Also write the volume as VTK image data (.vti, for ParaView).
    #[arg(help_heading = "Output", long)]
    pub vti: Option<PathBuf>,
    /// Also write the finest-level coordinate triples (layout: docs/formats.md, "The triples
    /// file").
    #[arg(help_heading = "Output", long)]
    pub triples: Option<PathBuf>,
    /// Also write a contact sheet (exemplar beside orthogonal slices).
    #[arg(help_heading = "Output", long)]
    pub sheet: Option<PathBuf>,
    /// Print a JSON summary on stdout.
    #[arg(help_heading = "Output", long)]
    pub json: bool,
    /// Time each kernel (waits for the device after every kernel) and report the times.
    #[arg(long, help_heading = "Performance")]
    pub profile: bool,
}

impl SolidArgs {
    /// The volume output `-o` names (by extension or `--format`) for the box `region`, with
    /// its texture and OpenVDB options.
    pub fn volume_output(&self, region: Box3) -> crate::Result<VolumeOutput> {
        let texture = crate::io::ktx2::TextureOptions {
            srgb: self.srgb,
            mips: self.mips,
        };
        let mut output = VolumeOutput::resolve(&self.output, "-o", self.format, texture)?;
        // (The VDB transform stores 1 / size^2 too, so the size stays far from both ends of
        // f64.)
        if !crate::io::vdb::VOXEL_SIZE_RANGE.contains(&self.voxel_size) {
            return Err(Error::invalid(
                format!("--voxel-size {}", crate::util::number_text(self.voxel_size)),
                "must be a number from 1e-6 to 1e6",
            ));
        }
        if output.format != crate::io::volume_file::VolumeFormat::Vdb && self.voxel_size != 1.0 {
            return Err(Error::invalid(
                "--voxel-size",
                "only OpenVDB volumes (.vdb) are placed in world units",
            ));
        }
        output.vdb = crate::io::vdb::VdbOptions {
            voxel_size: self.voxel_size,
            origin: region.lo.map(|c| c as f64 * self.voxel_size),
            ..Default::default()
        };
        Ok(output)
    }
}

/// `--coarse-cache N`: a period the cache can have (checked again with the other parameters),
/// so that `-1` or `x` are named as such rather than as numbers out of u32's range.
pub fn parse_coarse_cache(text: &str) -> Result<u32, String> {
    text.trim()
        .parse::<u32>()
        .ok()
        .filter(|n| crate::lazy::check_coarse_cache(*n).is_ok())
        .ok_or_else(|| {
            format!(
                "expected a multiple of 64 in {:?}",
                crate::lazy::COARSE_CACHE_PERIODS
            )
        })
}

/// `--max-group N`: a group side the engine takes ([`limits::check_max_group`]: whole bricks
/// within [`limits::MAX_GROUP_SIDES`]).
pub fn parse_max_group(text: &str) -> Result<u32, String> {
    text.trim()
        .parse::<u32>()
        .ok()
        .filter(|&n| limits::check_max_group(n).is_ok())
        .ok_or_else(|| {
            format!(
                "expected a multiple of 4 in {}..={}",
                limits::MAX_GROUP_SIDES.start(),
                limits::MAX_GROUP_SIDES.end()
            )
        })
}

/// Largest --size accepted before the memory estimate is even computed.
pub const MAX_SIZE: u32 = limits::MAX_BOX_SIDE;

/// Refuse a box whose synthesis would not fit in memory, before allocating anything for it:
/// the engine's working set and this command's outputs (`what` names the request in the error).
pub fn check_memory(what: &str, b: Box3, args: &SolidArgs) -> crate::Result<u64> {
    let output = args.volume_output(b)?;
    output.check(&args.output, b.size())?;
    let size = b.size().map(|d| d as u64);
    let group = args.solid.planned_group();
    // The outputs this command holds: slabs of the volume (four bytes a voxel cover up to four
    // channels; triples add twelve) and, for the outputs made from the whole volume, all of it.
    let per_voxel = 4 + if args.triples.is_some() { 12 } else { 0 };
    let slab = size[0] * size[1] * size[2].min(group as u64) * per_voxel;
    let keeps_volume = args.vti.is_some()
        || args.flipbook.is_some()
        || args.sheet.is_some()
        || args.slices.is_some();
    let whole = b.voxels() * 4 * (keeps_volume as u64 + output.format.holds_whole_volume() as u64);
    crate::solid::memory::check_box(what, size, group, args.solid.coarse_cache, slab + whole)
}

/// All z slices in a grid of exactly N tiles (see [`crate::io::flipbook`]).
pub fn flipbook(v: &Volume) -> image::RgbaImage {
    crate::io::flipbook::to_image(v)
}

fn rgba(p: &[u8]) -> image::Rgba<u8> {
    match p.len() {
        1 => image::Rgba([p[0], p[0], p[0], 255]),
        3 => image::Rgba([p[0], p[1], p[2], 255]),
        4 => image::Rgba([p[0], p[1], p[2], p[3]]),
        _ => image::Rgba([p[0], p[0], p[0], 255]),
    }
}

fn z_slice(v: &Volume, z: u32) -> image::RgbaImage {
    image::RgbaImage::from_fn(v.nx, v.ny, |x, y| rgba(v.at(x, y, z)))
}

pub fn run(args: SynthArgs, quiet: bool) -> anyhow::Result<()> {
    limits::check_size(&format!("--size {}", args.size), args.size as i64)?;
    let n = args.size as i32;
    if args.tileable {
        crate::lazy::check_tileable_size(args.size)?;
    }
    if args.tileable && args.solid.solid.coarse_cache.is_some() {
        return Err(Error::invalid(
            "--coarse-cache with --tileable",
            "the cache builds regions of the infinite solid; a tileable solid is its own \
             periodic definition: give one or the other",
        )
        .into());
    }
    let region = Box3::new([0; 3], [n; 3]);
    check_memory(&format!("--size {}", args.size), region, &args.solid)?;
    run_box(&args.solid, region, args.tileable, quiet)
}

/// Parse and check `--box X0,Y0,Z0,X1,Y1,Z1` for a volume held whole (sides up to MAX_SIZE).
pub fn parse_box(text: &str) -> crate::Result<Box3> {
    parse_box_within(text, MAX_SIZE as i64)
}

/// Parse and check `--box X0,Y0,Z0,X1,Y1,Z1` with sides up to `max_side` voxels.
pub fn parse_box_within(text: &str, max_side: i64) -> crate::Result<Box3> {
    let what = format!("--box {text}");
    let v: Vec<i64> = text
        .split(',')
        .map(|t| t.trim().parse::<i64>())
        .collect::<Result<_, _>>()
        .map_err(|_| Error::invalid(&what, "expected six integers X0,Y0,Z0,X1,Y1,Z1"))?;
    if v.len() != 6 {
        return Err(Error::invalid(
            &what,
            "expected six integers X0,Y0,Z0,X1,Y1,Z1",
        ));
    }
    limits::checked_box(&what, [v[0], v[1], v[2]], [v[3], v[4], v[5]], max_side)
}

pub fn run_region(args: RegionArgs, quiet: bool) -> anyhow::Result<()> {
    if super::region_zarr::is_zarr_output(&args.solid) {
        // Chunk by chunk: memory is one chunk's, so the box may exceed one volume's limit.
        let b = parse_box_within(&args.region, super::region_zarr::MAX_ZARR_SIDE)?;
        return super::region_zarr::run(b, &args.solid, &args.zarr, quiet);
    }
    args.zarr.check_unused()?;
    let b = parse_box(&args.region)?;
    check_memory(&format!("--box {}", args.region), b, &args.solid)?;
    run_box(&args.solid, b, false, quiet)
}

fn run_box(args: &SolidArgs, region: Box3, tileable: bool, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&args.output, "-o")?;
    // (The triples' own format takes any name.)
    for (flag, p, format, extension) in [
        ("--flipbook", &args.flipbook, "a PNG image", Some("png")),
        ("--vti", &args.vti, "VTK image data", Some("vti")),
        ("--sheet", &args.sheet, "a PNG image", Some("png")),
        ("--triples", &args.triples, "", None),
    ] {
        if let Some(p) = p {
            atomic::check_output_path(p, flag)?;
            if let Some(extension) = extension {
                atomic::check_output_extension(p, flag, format, &[extension])?;
            }
        }
    }
    if let Some(d) = &args.slices {
        atomic::check_output_dir(d, "--slices")?;
        // The slices' directory is new or empty and holds the slices alone.
        let files = [
            ("-o", Some(&args.output)),
            ("--flipbook", args.flipbook.as_ref()),
            ("--vti", args.vti.as_ref()),
            ("--sheet", args.sheet.as_ref()),
            ("--triples", args.triples.as_ref()),
        ];
        for (flag, p) in files {
            if let Some(p) = p {
                atomic::check_output_outside(p, flag, d, "--slices")?;
            }
        }
    }
    let params = args.solid.synth_params();
    params.validate()?;
    let start = Instant::now();
    let (compute, analysis) = open_and_analyze(&args.solid.input, quiet || args.json)?;
    let analysis_s = start.elapsed().as_secs_f64();
    let bar = super::progress_bar(quiet || args.json);
    let report = |m: &str, f: f32| {
        bar.report(m, f);
    };
    let synth_start = Instant::now();
    let mut solid = args.solid.solid(&analysis, &compute, args.profile, None)?;
    let synth = solid.synthesizer();
    tracing::debug!(
        "synthesizer built in {:.1} ms",
        synth_start.elapsed().as_secs_f64() * 1e3
    );
    // The synthesizer keeps what it reads; of the analysis the outputs need only the
    // exemplars' size (triples) and images (sheet), so the rest (11 MiB for the built-in
    // exemplar) is not held through the synthesis.
    let finest = &analysis.exemplar(0).levels[0].image;
    let exemplar_size = [finest.width, finest.height];
    let sheet_exemplars: Option<Vec<_>> = args.sheet.as_ref().map(|_| {
        (0..if analysis.shared { 1 } else { 3 })
            .map(|a| {
                analysis.exemplar(a).levels[0]
                    .image
                    .select_channels(0..analysis.color_channels)
            })
            .collect()
    });
    drop(analysis);
    // The volume is written as it is synthesized, a slab of z slices at a time (bounded
    // memory with --max-group); it is kept whole only for the outputs that need all of it.
    let dims = region.size();
    let channels = synth.color_channels();
    let mut volume_out =
        VolumeWriter::create(&args.output, args.volume_output(region)?, dims, channels)?;
    // Triples cost memory (and a read-back): only when asked for.
    let mut triples_out = args
        .triples
        .as_deref()
        .map(|p| super::triples::TriplesWriter::create(p, dims, exemplar_size))
        .transpose()?;
    let want_triples = triples_out.is_some();
    let keep_volume = args.vti.is_some()
        || args.flipbook.is_some()
        || args.sheet.is_some()
        || args.slices.is_some();
    let mut kept = keep_volume.then(|| Volume::new(dims[0], dims[1], 0, channels));
    let mut take = |slab: &Volume, triples: &[u32]| -> crate::Result<()> {
        let timer = Instant::now();
        volume_out.write_slab(slab)?;
        tracing::debug!(
            "slab of {} z slices written in {:.1} ms",
            slab.nz,
            timer.elapsed().as_secs_f64() * 1e3
        );
        if let Some(t) = &mut triples_out {
            t.write(triples)?;
        }
        if let Some(v) = &mut kept {
            v.data.extend_from_slice(&slab.data);
            v.nz += slab.nz;
        }
        Ok(())
    };
    let sink = |slab: crate::lazy::Slab| take(slab.volume, slab.triples);
    if tileable {
        synth.synthesize_tileable_slabs(dims[0], &report, want_triples, sink)?;
    } else {
        synth.synthesize_slabs(region, &report, want_triples, sink)?;
    }
    let synth_s = synth_start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    // Every output is staged and they appear together at the end: a failure on the way (the
    // flipbook's disk full, an interrupt) leaves none of them.
    let mut outputs = atomic::Outputs::new();
    outputs.stage(volume_out.finish()?);
    if let Some(t) = triples_out {
        outputs.stage(t.finish());
    }
    let volume = kept.unwrap_or_else(|| Volume::new(0, 0, 0, channels));
    if let Some(p) = &args.vti {
        outputs.write_file(p, &crate::io::vti::to_checked_bytes(&volume, p)?)?;
    }
    if let Some(p) = &args.flipbook {
        outputs.save_png(p, &flipbook(&volume))?;
    }
    if let (Some(p), Some(exemplars)) = (&args.sheet, &sheet_exemplars) {
        outputs.save_png(p, &contact_sheet(&volume, exemplars))?;
    }
    if let Some(dir) = &args.slices {
        let staging = outputs.directory(dir)?;
        for z in 0..volume.nz {
            let path = dir.join(format!("slice_{z:04}.png"));
            let png = atomic::rgba_png_bytes(&z_slice(&volume, z))?;
            std::fs::write(staging.join(path.file_name().expect("a file name")), png)
                .map_err(|e| Error::io(&path, e))?;
        }
    }
    outputs.commit()?;
    let kernels: std::collections::BTreeMap<String, KernelTime> = synth
        .kernel_times()
        .map(|t| {
            t.iter()
                .map(|(k, (d, n))| {
                    let time = KernelTime {
                        seconds: d.as_secs_f64(),
                        calls: *n as u64,
                    };
                    (k.to_string(), time)
                })
                .collect()
        })
        .unwrap_or_default();
    if args.json {
        print_summary(&BoxSummary {
            output: &args.output,
            r#box: [region.lo, region.hi],
            seed: args.solid.seed,
            jitter: args.solid.jitter,
            candidates: args.solid.candidates,
            passes: args.solid.passes,
            color: args.solid.color,
            analysis_seconds: analysis_s,
            synthesis_seconds: synth_s,
            peak_rss_bytes: crate::util::memory::peak_rss_bytes(),
            backend: compute.describe(),
            kernels: &kernels,
            stats: synth.last_stats(),
        });
    } else if !quiet {
        for (k, v) in &kernels {
            eprintln!("  kernel {k:<9} {:>8.3} s in {} calls", v.seconds, v.calls);
        }
        if let Some(st) = synth.last_stats() {
            eprintln!(
                "  voxels synthesized per level (coarsest first): {:?}; peak state {:.1} MiB",
                st.voxels_per_level,
                st.peak_state_bytes as f64 / (1 << 20) as f64
            );
        }
        let d = region.size();
        eprintln!(
            "synthesized {}x{}x{} at {:?} in {synth_s:.2} s (analysis {analysis_s:.2} s) -> {}",
            d[0],
            d[1],
            d[2],
            region.lo,
            args.output.display()
        );
    }
    Ok(())
}

/// `synth --json` and `region --json`.
#[derive(serde::Serialize)]
struct BoxSummary<'a> {
    output: &'a Path,
    /// The half-open box, [lo, hi].
    r#box: [[i32; 3]; 2],
    seed: u64,
    jitter: f32,
    candidates: CandidateMode,
    passes: crate::lazy::PassSchedule,
    color: ColorSource,
    analysis_seconds: f64,
    synthesis_seconds: f64,
    peak_rss_bytes: Option<u64>,
    backend: String,
    /// Per kernel, with `--profile`.
    kernels: &'a std::collections::BTreeMap<String, KernelTime>,
    stats: Option<&'a crate::lazy::SynthStats>,
}
