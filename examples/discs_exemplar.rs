//! Writes the generated two-region exemplar used by the region-separation benchmarks (red discs
//! on a blue ground) and its mask. Run:
//! `cargo run --release --example discs_exemplar -- SIZE COUNT RADIUS OUT_DIR`
//! (BENCHMARKS.md uses 128 24 9 -> OUT_DIR/discs.png, OUT_DIR/discs_mask.png).

use solidsynth::exemplar::procedural;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or(default.to_string());
    let size: u32 = arg(1, "128").parse().expect("SIZE");
    let count: u32 = arg(2, "24").parse().expect("COUNT");
    let radius: f32 = arg(3, "9").parse().expect("RADIUS");
    let dir = std::path::PathBuf::from(arg(4, "."));
    std::fs::create_dir_all(&dir).expect("create OUT_DIR");
    let (img, mask) = procedural::discs(size, count, radius, 5);
    for (image, name) in [(img, "discs.png"), (mask, "discs_mask.png")] {
        let path = dir.join(name);
        image.to_dynamic().save(&path).expect("write");
        println!("wrote {}", path.display());
    }
}
