//! An exemplar image to a solid texture: a 64^3 box written as NRRD, and its middle z slice as a
//! PNG. `cargo run --release --example 01_volume -- [IMAGE] [OUT_DIR]` (no image: the built-in
//! exemplar; the CPU backend, so it runs anywhere).
use solidsynth::{Box3, Solid};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut builder = Solid::builder().seed(5).cpu();
    if let Some(path) = args.next().filter(|a| !a.is_empty()) {
        let image = solidsynth::exemplar::load_image(path.as_ref(), "IMAGE")?;
        builder = builder.exemplar(image);
    }
    let out = std::path::PathBuf::from(args.next().unwrap_or_else(|| "example-out".into()));
    std::fs::create_dir_all(&out)?;

    // Analysis (a few seconds for a 128^2 image), then any box of the infinite solid.
    let mut solid = builder
        .progress(|stage, f| eprint!("\r{:>3.0}% {stage:<60}", f * 100.0))
        .build()?;
    eprintln!();
    let started = std::time::Instant::now();
    let volume = solid.region(Box3::new([0, 0, 0], [64, 64, 64]))?;
    eprintln!("64^3 in {:.2} s", started.elapsed().as_secs_f64());

    solidsynth::io::nrrd::save(&volume, &out.join("volume.nrrd"))?;
    let z = volume.nz / 2;
    let slice = image::RgbaImage::from_fn(volume.nx, volume.ny, |x, y| {
        let p = volume.at(x, y, z);
        let c = |i: usize| p[i.min(p.len() - 1)];
        image::Rgba([c(0), c(1), c(2), 255])
    });
    slice.save(out.join("slice.png"))?;
    println!(
        "wrote {} and {}",
        out.join("volume.nrrd").display(),
        out.join("slice.png").display()
    );
    Ok(())
}
