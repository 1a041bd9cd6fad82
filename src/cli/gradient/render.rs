//! `gradient render`: a .gsolid rendered into a volume, or a slice of any orientation as a PNG.

use super::RenderArgs;
use crate::cli::output::print_summary;
use crate::gradient::file::GradientFile;
use crate::gradient::regions::Blend;
use crate::gradient::Query;
use crate::io::atomic;
use crate::Error;
use std::path::Path;
use std::time::Instant;

/// `gradient render`: a volume in the output's format, or with `--normal` a slice.
pub(super) fn render(a: RenderArgs, quiet: bool) -> anyhow::Result<()> {
    atomic::check_output_path(&a.output, "-o")?;
    // A volume's format is known (or refused) before anything is read.
    let output = match a.normal {
        None => crate::io::volume_file::VolumeOutput::resolve(
            &a.output,
            "-o",
            a.format,
            Default::default(),
        )?,
        Some(_) => {
            atomic::check_output_extension(&a.output, "-o", "a PNG slice", &["png"])?;
            crate::io::volume_file::VolumeOutput {
                format: crate::io::volume_file::VolumeFormat::Png,
                texture: Default::default(),
                vdb: Default::default(),
            }
        }
    };
    let solid = GradientFile::load(&a.input)?;
    if let Some(normal) = &a.normal {
        return render_slice(&a, &solid, normal, quiet);
    }
    let n = a.size.map(|s| [s; 3]).unwrap_or_else(|| solid.size());
    if n.iter().any(|&s| s > 2048) {
        return Err(
            Error::invalid(format!("--size {}", n[0]), "a volume side is at most 2048").into(),
        );
    }
    output.check(&a.output, n)?;
    solid.check_render_memory(n)?;
    let compute = a.backend.open()?;
    let start = Instant::now();
    let mut v = crate::volume::Volume::new(n[0], n[1], n[2], solid.channels());
    v.data = solid.render_volume_u8(n, &compute, blend_of(&a), !a.no_detail)?;
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
    Ok(())
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
    let centre = solid.size().map(|e| (e as f64 - 1.0) / 2.0);
    let spec = crate::lazy::cut::CutSpec {
        origin: match &a.origin {
            Some(o) => crate::cli::cut::triple(o, "--origin")?,
            None => centre,
        },
        normal: crate::cli::cut::triple(normal, "--normal")?,
        up: a
            .up
            .as_deref()
            .map(|u| crate::cli::cut::triple(u, "--up"))
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
    if a.json {
        print_summary(&RenderSummary {
            output: &a.output,
            size: [spec.size, spec.size, 1],
            channels: solid.channels(),
            seconds: start.elapsed().as_secs_f64(),
            backend: compute.describe(),
        });
    } else if !quiet {
        eprintln!(
            "rendered a {0}x{0} slice in {1:.3} s -> {2}",
            spec.size,
            start.elapsed().as_secs_f64(),
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

/// `gradient render --json`: a volume's size, or a slice's as N x N x 1; `channels` are the
/// solid's (a slice's PNG holds them as gray or RGB(A)).
#[derive(serde::Serialize)]
struct RenderSummary<'a> {
    output: &'a Path,
    size: [u32; 3],
    channels: u32,
    seconds: f64,
    backend: String,
}
