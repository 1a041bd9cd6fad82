//! `solidsynth surface`: the solid baked onto a mesh surface (binary glTF, or OBJ + MTL + PNG).

use super::analyze::load_or_analyze;
use super::synth::SolidParams;
use clap::Args;
use solidsynth::io::atomic;
use solidsynth::mesh::{self, bake, Placement};
use solidsynth::Error;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct SurfaceArgs {
    #[command(flatten)]
    pub solid: SolidParams,
    /// Mesh (.obj, .ply or .ply.gz); open or non-manifold meshes are fine.
    #[arg(long)]
    pub mesh: PathBuf,
    /// The mesh is scaled so its longest side spans this many finest-level voxels.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=1048576))]
    pub resolution: u32,
    /// Voxels per texel step along a triangle's edges: each triangle's atlas cell is sized to
    /// the triangle (default 1, grown only when the atlas would not fit 16384^2 or memory).
    #[arg(long, conflicts_with = "texels")]
    pub texel_size: Option<f64>,
    /// Instead of cells sized to their triangles, the same square cell of T x T texels for every
    /// triangle (2..=256).
    #[arg(long)]
    pub texels: Option<u32>,
    /// Output: .glb (texture embedded) or .obj (writes .mtl and .png beside it).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

/// The files an output path stands for: (main, Some((mtl, png)) for OBJ).
fn outputs(path: &Path) -> solidsynth::Result<Option<(PathBuf, PathBuf)>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("glb") => Ok(None),
        Some("obj") => Ok(Some((
            path.with_extension("mtl"),
            path.with_extension("png"),
        ))),
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
    let place = Placement::fit(&mesh, args.resolution);
    // Per texel: its image pixel (4 bytes), its index and colour while its group places it (8;
    // a group may hold the whole surface), then its PNG (at most about 4), and a bit of
    // bookkeeping; the requested bricks' are checked below. Refuse before allocating when that
    // cannot fit.
    let bytes_per_texel = 16;
    let available = super::synth::available_memory();
    // The layout, how to say it, and the flag that chose it (for errors).
    let fewer = if args.texels.is_some() {
        "a smaller --texels"
    } else {
        "a larger --texel-size"
    };
    let (atlas, texel_size, layout, flag) = match args.texels {
        Some(texels) => (
            bake::Atlas::new(mesh.triangles.len(), texels)?,
            None,
            format!("{texels} x {texels} texels per triangle"),
            format!("--texels {texels}"),
        ),
        None => {
            let (atlas, size) =
                bake::Atlas::fitted_within(&mesh, &place, args.texel_size, |atlas| {
                    atlas.texel_count() * bytes_per_texel <= available
                })?;
            (
                atlas,
                Some(size),
                format!("cells fitted at {size} voxels per texel"),
                format!("--texel-size {size}"),
            )
        }
    };
    let estimate = atlas.texel_count() * bytes_per_texel;
    if estimate > available {
        return Err(Error::invalid(
            flag,
            format!(
                "a {}x{} atlas needs about {:.1} GiB, {:.1} GiB is available; use fewer texels \
                 ({fewer})",
                atlas.width,
                atlas.height,
                estimate as f64 / (1u64 << 30) as f64,
                available as f64 / (1u64 << 30) as f64
            ),
        )
        .into());
    }
    let start = Instant::now();
    // The texel positions are visited twice (for their bricks, then for their colours) rather
    // than listed: at 1024^3 the list is 75 MB.
    let mut wanted = solidsynth::lazy::bricks::BrickSet::default();
    atlas.for_each_texel_voxel(&mesh, &place, |_, p| wanted.add(p));
    let wanted = wanted.finish();
    super::synth::check_sparse_memory(
        &format!("surface --resolution {}", args.resolution),
        wanted.len() as u64,
        args.resolution as f64,
        estimate,
        &args.solid,
        args.solid.planned_group(),
    )?;
    // The analysis (loaded or computed) is not part of the surface's time.
    let analysis_start = Instant::now();
    let compute = args.solid.input.backend.open()?;
    let analysis = load_or_analyze(&args.solid.input, &compute, quiet || args.json)?;
    let analysis_time = analysis_start.elapsed();
    let bar = super::progress_bar(quiet || args.json);
    let report = |m: &str, f: f32| {
        bar.set_position((f * 1000.0) as u64);
        bar.set_message(m.to_string());
    };
    let mut synth = args.solid.synthesizer(&analysis, &compute, false)?;
    // The synthesizer keeps what it reads: the analysis (10 MiB for the built-in exemplar) is
    // not held through the synthesis.
    drop(analysis);
    // Each group's colours go into the atlas as the group finishes (the texels of the
    // triangles near it whose voxels it holds), so the request's colours are never held whole
    // (the bunny at 1024: 52 MB of them). Every texel's voxel is in exactly one group; texels
    // outside every cell take the colour of one surface voxel, as `for_each_texel_voxel` says.
    let texels = atlas.texel_count() as usize;
    let channels = synth.color_channels();
    // Three bytes a texel unless the solid has a fourth channel: the atlas is the largest
    // buffer the bake holds (the bunny at 1024: 16 MB as RGB, 22 MB as RGBA).
    let texel_bytes = if channels >= 4 { 4 } else { 3 };
    let mut pixels = vec![0u8; texels * texel_bytes];
    let mut placed = vec![0u64; texels.div_ceil(64)];
    let uncovered_voxel = atlas.uncovered_texel_voxel(&mesh, &place);
    let mut uncovered_color = None;
    let mut bake_group = |group: solidsynth::lazy::BrickColors| {
        use rayon::prelude::*;
        let (lo, hi) = solidsynth::lazy::bricks::bounds(&group.bricks).expect("a group has bricks");
        let (lo, hi) = (lo.map(|v| v * 4), hi.map(|v| v * 4 + 3));
        // The group's texels, found in parallel (the cores are otherwise idle between groups),
        // then placed.
        // (Texel indices fit u32: atlases are at most 16384^2.)
        let found: Vec<Vec<(u32, u32)>> = atlas
            .triangles_near(&mesh, &place, lo, hi)
            .par_iter()
            .map(|&t| {
                let mut last = None;
                let mut out = Vec::new();
                atlas.for_each_texel_voxel_of(&mesh, &place, t, |i, p| {
                    // (Most texels of the triangles at the group's edges fall outside it.)
                    if (0..3).any(|k| p[k] < lo[k] || p[k] > hi[k]) {
                        return;
                    }
                    if let Some(c) = group.color_near(p, &mut last) {
                        out.push((i as u32, c));
                    }
                });
                out
            })
            .collect();
        for (i, c) in found.into_iter().flatten() {
            let i = i as usize;
            pixels[texel_bytes * i..texel_bytes * (i + 1)]
                .copy_from_slice(&bake::atlas_pixel(c, channels)[..texel_bytes]);
            placed[i / 64] |= 1 << (i % 64);
        }
        if uncovered_color.is_none() {
            uncovered_color = group.color(uncovered_voxel);
        }
    };
    // Groups are baked on a thread of their own while the next ones are synthesized: on a
    // GPU the bake of the bunny's groups took as long as planning and running them (session
    // 30). One group waits in the channel, so with the one being baked, the one the
    // synthesizer hands over and (on a GPU) the one whose colours are still coming back, about
    // four groups' colours are held at once.
    std::thread::scope(|scope| -> anyhow::Result<()> {
        let (finished, to_bake) = std::sync::mpsc::sync_channel(1);
        let baker = scope.spawn(move || to_bake.into_iter().for_each(&mut bake_group));
        let synthesized = synth.synthesize_bricks_by_group(&wanted, &report, |group| {
            finished
                .send(group)
                .map_err(|_| solidsynth::Error::Internal("the atlas bake stopped".into()))
        });
        drop(finished);
        if let Err(panic) = baker.join() {
            std::panic::resume_unwind(panic);
        }
        Ok(synthesized?)
    })?;
    drop(wanted);
    let uncovered_color = uncovered_color.expect("the uncovered texels' voxel is requested");
    let uncovered_pixel = bake::atlas_pixel(uncovered_color, channels);
    for (i, p) in pixels.chunks_exact_mut(texel_bytes).enumerate() {
        if placed[i / 64] & (1 << (i % 64)) == 0 {
            p.copy_from_slice(&uncovered_pixel[..texel_bytes]);
        }
    }
    drop(placed);
    // Of the synthesizer, baking needs only these: its level data and tables (on a GPU, its
    // buffers) are freed before the atlas's PNG is made.
    let stats = synth.last_stats().cloned().unwrap_or_default();
    drop(synth);
    bar.finish_and_clear();
    let seconds = (start.elapsed() - analysis_time).as_secs_f64();
    let (width, height) = (atlas.width, atlas.height);
    let png = if texel_bytes == 4 {
        atomic::png_bytes(&image::RgbaImage::from_raw(width, height, pixels).expect("sized"))?
    } else {
        atomic::png_bytes(&image::RgbImage::from_raw(width, height, pixels).expect("sized"))?
    };
    match &extra {
        None => atomic::write_with(&args.output, |f| {
            mesh::glb::write_glb(f, &mesh, &atlas, &png)
        })?,
        Some((mtl, png_path)) => {
            // The three files appear together or not at all.
            let name = |p: &Path| p.file_name().unwrap().to_string_lossy().into_owned();
            let mut outputs = atomic::Outputs::new();
            outputs.write_file(png_path, &png)?;
            outputs.write_file(mtl, bake::mtl_text(&name(png_path)).as_bytes())?;
            outputs.write_file(
                &args.output,
                bake::obj_text(&mesh, &atlas, &name(mtl)).as_bytes(),
            )?;
            outputs.commit()?;
        }
    }
    let finest = stats.voxels_per_level.last().copied().unwrap_or(0);
    let fraction = finest as f64 / (args.resolution as f64).powi(3);
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "output": args.output, "triangles": mesh.triangles.len(), "resolution": args.resolution,
                "texels": args.texels, "texel_size": texel_size, "atlas": [atlas.width, atlas.height],
                "max_texel_step_voxels": atlas.max_texel_step(&mesh, &place),
                "synthesis_seconds": seconds, "stats": stats,
                "finest_fraction_of_volume": fraction,
                "peak_rss_bytes": solidsynth::util::memory::peak_rss_bytes(),
                "backend": compute.describe(),
            })
        );
    } else if !quiet {
        eprintln!(
            "surface of {} triangles at {}^3: atlas {}x{} ({layout}, longest texel step {:.2} \
             voxels) in {seconds:.2} s; \
             finest voxels synthesized {finest} ({:.3}% of the volume), per level {:?}, peak state \
             {:.1} MiB -> {}",
            mesh.triangles.len(),
            args.resolution,
            atlas.width,
            atlas.height,
            atlas.max_texel_step(&mesh, &place),
            fraction * 100.0,
            stats.voxels_per_level,
            stats.peak_state_bytes as f64 / (1 << 20) as f64,
            args.output.display()
        );
    }
    Ok(())
}
