//! Regenerates the repository's generated images: the built-in default exemplar and the test
//! fixtures. Run: `cargo run --example generate_fixtures`.

use solidsynth::exemplar::procedural;

fn main() {
    let save = |img: solidsynth::exemplar::Image, path: &str| {
        img.to_dynamic().save(path).expect(path);
        println!("wrote {path}");
    };
    // The built-in exemplar: a slice of a procedural solid (palette Voronoi cells), so a
    // consistent solid texture for it exists.
    save(
        solidsynth::metrics::slices::slice(&procedural::cells_3d(128, 120, 6), 2, 0),
        "assets/default-exemplar.png",
    );
    std::fs::create_dir_all("tests/fixtures").unwrap();
    save(
        procedural::cobblestone(32, 6, 3),
        "tests/fixtures/cells32.png",
    );
    save(procedural::marble(32, 11), "tests/fixtures/marble32.png");
    save(procedural::stripes(32, 8), "tests/fixtures/stripes32.png");
    // CC0 crops (scikit-image data, via ../shared/exemplars) when that folder is present.
    for name in ["brick", "gravel"] {
        let src = format!("../shared/exemplars/cc0_{name}.png");
        if let Ok(img) = image::open(&src) {
            let crop = image::imageops::crop_imm(&img.to_luma8(), 128, 128, 64, 64).to_image();
            let path = format!("tests/fixtures/cc0_{name}64.png");
            crop.save(&path).unwrap();
            println!("wrote {path}");
        }
    }
}
