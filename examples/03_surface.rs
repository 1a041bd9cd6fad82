//! A solid baked onto a mesh: every atlas texel is the solid's voxel at its 3D point, written
//! as a binary glTF. `cargo run --release --example 03_surface -- [MESH.obj|.ply] [OUT.glb]`
//! (no mesh: an octahedron).
use solidsynth::solid::surface::{AtlasLayout, SurfacePlan};
use solidsynth::Solid;

const OCTAHEDRON: &str = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n\
    f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mesh = match args.next().filter(|a| !a.is_empty()) {
        Some(path) => solidsynth::mesh::load(path.as_ref())?,
        None => solidsynth::mesh::parse_obj(OCTAHEDRON.as_bytes(), "octahedron")?,
    };
    let out = args.next().unwrap_or_else(|| "surface.glb".into());
    // Planned before anything is synthesized: the atlas and its memory (refused if too large).
    let plan = SurfacePlan::new(
        &mesh,
        "the mesh",
        96,
        AtlasLayout::Texels {
            texels: 16,
            gutter: 0,
        },
        None,
        128,
    )?;
    let mut solid = Solid::builder().seed(11).cpu().build()?;
    let started = std::time::Instant::now();
    let baked = solid.bake_surface(&mesh, &plan)?;
    println!(
        "{} triangles baked into a {}x{} atlas in {:.2} s",
        mesh.triangles.len(),
        baked.width,
        baked.height,
        started.elapsed().as_secs_f64()
    );
    let png = baked.png()?;
    let mut file = std::fs::File::create(&out)?;
    solidsynth::mesh::glb::write_glb(&mut file, &mesh, &plan.atlas, &png)?;
    println!("wrote {out}");
    Ok(())
}
