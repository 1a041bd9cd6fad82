//! Writes evaluation control volumes to a folder: a genuine 3D texture (`cells.nrrd`) with an
//! exemplar cut from another instance (`cells-exemplar.png`). Used to time `solidsynth eval`.
//! Run: `cargo run --release --example control_volumes -- OUT_DIR [SIZE]`.

use solidsynth::exemplar::procedural;
use solidsynth::metrics::slices::slice;

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(args.next().expect("OUT_DIR"));
    let size: u32 = args.next().map(|s| s.parse().unwrap()).unwrap_or(128);
    std::fs::create_dir_all(&dir).unwrap();
    let cells: u32 = args
        .next()
        .map(|s| s.parse().unwrap())
        .unwrap_or((size * size * size / 2600).max(20));
    let v = procedural::cells_3d(size, cells, 5);
    solidsynth::io::nrrd::save(&v, &dir.join("cells.nrrd")).unwrap();
    slice(&procedural::cells_3d(size, cells, 6), 2, 0)
        .to_dynamic()
        .save(dir.join("cells-exemplar.png"))
        .unwrap();
    println!(
        "wrote {}/cells.nrrd ({size}^3) and cells-exemplar.png",
        dir.display()
    );
}
