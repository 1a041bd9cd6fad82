//! Lapped solid textures (Takayama, Okabe, Ijiri, Igarashi 2008): many overlapping copies of a
//! small solid exemplar pasted inside a tetrahedralized model along a tensor field, so a large
//! solid textured model costs a tet mesh and per-tet texture coordinates, no voxels.
//!
//! Pipeline ([`build`]): triangle mesh -> tet mesh ([`stuffing`], inside test by [`winding`]
//! number) -> tensor field from a constraints file ([`field`]) -> pasting loop ([`paste`]) ->
//! [`model::LstModel`] (the `.lst` file). Consumers: planar cuts ([`cut`]), surface bakes
//! ([`bake`]) and the GPU render (kernel `lapped_render`, of the [`scene`] a model gives).

pub mod bake;
pub mod camera;
pub mod cut;
pub mod exemplar;
pub mod field;
pub mod model;
pub mod paste;
pub mod scene;
pub mod shapes;
pub mod stuffing;
pub mod tetmesh;
pub mod winding;

use crate::error::Result;
use crate::mesh::Mesh;
use exemplar::SolidExemplar;
use field::{Constraints, Field};
use model::LstModel;
use std::time::Instant;

/// Default lattice resolution (cells along the longest side): ~5,000 tets for a bunny.
pub const DEFAULT_RESOLUTION: u32 = 12;
/// Patch scales within this factor of the mesh's longest side either way: a patch ten thousand
/// times smaller or larger than the model pastes nothing meaningful, and far beyond it the
/// field's least-squares solves lose their precision.
const SCALE_RANGE: f64 = 1e4;

/// Refuse `--scale` (`scale`) or a scale of the constraints file outside [`SCALE_RANGE`] of the
/// mesh's `extent`.
fn check_scales(
    scale: Option<f64>,
    constraints: &Constraints,
    constraints_name: &str,
    extent: f64,
) -> Result<()> {
    if let Some(s) = scale {
        check_scale(
            s,
            &format!("--scale {}", crate::util::number_text(s)),
            extent,
        )?;
    }
    if let Some(s) = constraints.scale {
        let named = format!("{constraints_name}: scale {}", crate::util::number_text(s));
        check_scale(s, &named, extent)?;
    }
    for (i, &(_, s)) in constraints.scales.iter().enumerate() {
        check_scale(
            s,
            &format!(
                "{constraints_name}: scales[{i}].scale {}",
                crate::util::number_text(s)
            ),
            extent,
        )?;
    }
    Ok(())
}

/// Refuse a patch scale (`what` names it) outside [`SCALE_RANGE`] of the mesh's `extent`.
fn check_scale(scale: f64, what: &str, extent: f64) -> Result<()> {
    let (lo, hi) = (extent / SCALE_RANGE, extent * SCALE_RANGE);
    if !(scale >= lo && scale <= hi) {
        return Err(crate::Error::invalid(
            what,
            format!(
                "must be within {SCALE_RANGE:e} times the mesh's longest side ({extent:.4}) \
                 either way: {lo:.3e} to {hi:.3e}"
            ),
        ));
    }
    Ok(())
}

/// Default patch scale: a third of the model's longest side per exemplar cube.
pub const DEFAULT_SCALE_FRACTION: f64 = 1.0 / 3.0;
/// Seed of the procedural splotch masks (part of the model: they are stored in it).
const MASK_SEED: u64 = 0x0051_07c4;

#[derive(Clone, Debug)]
pub struct FillOptions {
    pub resolution: u32,
    /// World size of one exemplar cube where the constraints give none.
    pub scale: Option<f64>,
    pub seed: u64,
}

impl Default for FillOptions {
    fn default() -> Self {
        FillOptions {
            resolution: DEFAULT_RESOLUTION,
            scale: None,
            seed: 1,
        }
    }
}

/// What a fill did, for `lapped fill` to report.
#[derive(Clone, Debug)]
pub struct FillReport {
    pub quality: tetmesh::Quality,
    pub stuffing: stuffing::StuffingStats,
    pub fill: paste::FillStats,
    pub default_scale: f64,
    pub mesh_seconds: f64,
    pub field_seconds: f64,
    pub fill_seconds: f64,
}

/// What a fill reads, each input with the name errors use for it.
pub struct FillInputs<'a> {
    pub mesh: &'a Mesh,
    pub mesh_name: &'a str,
    pub exemplar: SolidExemplar,
    pub exemplar_source: &'a str,
    pub constraints: &'a Constraints,
    pub constraints_name: &'a str,
}

/// Tetrahedralize the mesh, build the field and fill it with the exemplar.
pub fn build(
    inputs: FillInputs,
    opts: &FillOptions,
    progress: &dyn Fn(usize, usize),
) -> Result<(LstModel, FillReport)> {
    let FillInputs {
        mesh,
        mesh_name,
        exemplar,
        exemplar_source,
        constraints,
        constraints_name,
    } = inputs;
    // The scales are checked before the mesh is stuffed (a mesh without finite bounds is
    // refused by the stuffing, which names it).
    let (lo, hi) = mesh.bounds();
    let extent = (hi - lo).max_element();
    if extent.is_finite() && extent > 0.0 {
        check_scales(opts.scale, constraints, constraints_name, extent)?;
    }
    let start = Instant::now();
    let (tets, stuffing) = stuffing::stuff(mesh, opts.resolution, mesh_name)?;
    let quality = tets.quality();
    let mesh_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let winding = winding::Winding::new(mesh);
    constraints.check_inside(&winding, constraints_name)?;
    let default_scale = opts.scale.unwrap_or(extent * DEFAULT_SCALE_FRACTION);
    let field = Field::compute(&tets, constraints, default_scale)?;
    let masks = if constraints.kind.depth_varying() {
        exemplar::layered(MASK_SEED).to_vec()
    } else {
        vec![exemplar::splotch(MASK_SEED)]
    };
    let field_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let (patches, fill) = paste::fill(&tets, &field, &masks, opts.seed, progress)?;
    let fill_seconds = start.elapsed().as_secs_f64();
    let model = LstModel::from_patches(
        constraints.kind,
        opts.seed,
        exemplar_source.to_string(),
        exemplar,
        masks,
        tets,
        &patches,
    );
    Ok((
        model,
        FillReport {
            quality,
            stuffing,
            fill,
            default_scale,
            mesh_seconds,
            field_seconds,
            fill_seconds,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Volume;

    /// A small tileable exemplar: smooth colour waves, periodic over the cube.
    pub fn wave_exemplar(n: u32) -> SolidExemplar {
        let mut v = Volume::new(n, n, n, 3);
        let tau = std::f64::consts::TAU / n as f64;
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let c = v.at_mut(x, y, z);
                    c[0] = (128.0 + 100.0 * (tau * x as f64).sin()) as u8;
                    c[1] = (128.0 + 100.0 * (tau * y as f64).sin()) as u8;
                    c[2] = (128.0 + 100.0 * (tau * z as f64).cos()) as u8;
                }
            }
        }
        SolidExemplar::from_volume(&v, "waves").unwrap()
    }

    #[test]
    fn sphere_fills_deterministically_for_every_type() {
        let sphere = shapes::sphere(24, 12);
        let files = [
            r#"{"type": "0"}"#,
            r#"{"type": "1-a", "strokes": [[[0,0,-0.7],[0,0,0.7]]]}"#,
            r#"{"type": "1-b", "depth": {"inner": [[[0,0,-0.5],[0,0,0.5]]]}}"#,
            r#"{"type": "2-a", "strokes": [[[0.5,0,-0.5],[0.5,0,0.5]]], "depth": {"inner": [[[0,0,-0.5],[0,0,0.5]]]}}"#,
            r#"{"type": "2-b", "strokes": [[[0.5,0,-0.5],[0.5,0,0.5]]], "depth": {"inner": [[[0,0,-0.5],[0,0,0.5]]]}}"#,
        ];
        for json in files {
            let c = Constraints::parse(json.as_bytes(), "c.json").unwrap();
            let opts = FillOptions {
                resolution: 8,
                ..Default::default()
            };
            let run = || {
                build(
                    FillInputs {
                        mesh: &sphere,
                        mesh_name: "sphere",
                        exemplar: wave_exemplar(16),
                        exemplar_source: "waves",
                        constraints: &c,
                        constraints_name: "c.json",
                    },
                    &opts,
                    &|_, _| {},
                )
                .unwrap()
            };
            let (a, report) = run();
            let (b, _) = run();
            eprintln!("{json}: {report:?} layers {:.1}", a.mean_layers());
            assert_eq!(a.to_bytes(), b.to_bytes());
            assert!(a.layers.iter().all(|l| !l.is_empty()));
            assert_eq!(report.quality.inverted, 0);
            let parsed = LstModel::parse(&a.to_bytes()).unwrap();
            assert_eq!(parsed.to_bytes(), a.to_bytes());
        }
    }
}
