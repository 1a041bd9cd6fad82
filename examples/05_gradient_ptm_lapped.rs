//! The other three papers, one call each: a gradient solid synthesized from an exemplar, a
//! relightable (PTM) texture fitted and relit, a lapped solid texture filled into a sphere and
//! cut. `cargo run --release --example 05_gradient_ptm_lapped`
use solidsynth::gradient::synth::{synthesize, GradientSynthParams};
use solidsynth::lapped::field::Constraints;
use solidsynth::lapped::{self, FillInputs, FillOptions};
use solidsynth::ptm::{capture, fit, relight, Lighting, PtmFormat};
use solidsynth::Compute;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let compute = Compute::Cpu;
    // Gradient solid textures: a 24^3 periodic tricubic solid from the built-in exemplar.
    let exemplar = solidsynth::exemplar::default_exemplar();
    let params = GradientSynthParams {
        size: 24,
        iterations: 1,
        seed: 4,
        ..Default::default()
    };
    let (solid, _) = synthesize(&exemplar, &params, &compute, &|_, _| {})?;
    let solid = solid.to_gradient_solid()?;
    println!(
        "gradient solid: {:?} control points, {} channels",
        solid.dims, solid.channels
    );

    // Relightable textures: photographs under 12 lights, a fitted PTM, relit from the side.
    let photos = capture::synthetic(40, 12, 1);
    let ptm = fit::fit(&photos, PtmFormat::Rgb, "synthetic capture")?;
    let light = Lighting {
        lu: 0.7,
        lv: 0.0,
        specular: 0.2,
    };
    let rgb = relight::relight(&compute, &ptm, &light)?;
    println!(
        "PTM {}x{} relit: {} values",
        ptm.width,
        ptm.height,
        rgb.len()
    );

    // Lapped solid textures: a sphere filled with patches of a small solid exemplar, cut.
    let sphere = lapped::shapes::sphere(24, 12);
    let cube = solidsynth::Solid::builder()
        .seed(2)
        .cpu()
        .build()?
        .tileable(32)?;
    let exemplar = lapped::exemplar::SolidExemplar::from_volume(&cube, "tileable 32^3")?;
    let constraints = Constraints::isotropic();
    let inputs = FillInputs {
        mesh: &sphere,
        mesh_name: "sphere",
        exemplar,
        exemplar_source: "tileable 32^3",
        constraints: &constraints,
        constraints_name: "isotropic",
    };
    let opts = FillOptions {
        resolution: 6,
        ..Default::default()
    };
    let (model, _) = lapped::build(inputs, &opts, &|_, _| {})?;
    let spec = solidsynth::CutSpec {
        origin: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        up: None,
        size: 64,
        spacing: 2.5 / 64.0,
    };
    let cut = lapped::cut::cut(&model, &spec)?;
    println!(
        "lapped model: {} tets, cut {}x{}",
        model.mesh.tets.len(),
        cut.width(),
        cut.height()
    );
    Ok(())
}
