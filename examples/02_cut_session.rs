//! Planar cuts on demand: a warm session cuts the infinite solid anywhere, at any angle, and
//! prints each cut's latency. `cargo run --release --example 02_cut_session`
use solidsynth::CutSpec;
use solidsynth::Solid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The coarse-level cache (period 64) makes warm cuts synthesize only the finest level.
    let solid = Solid::builder()
        .seed(3)
        .coarse_cache(Some(64))
        .cpu()
        .build()?;
    let mut session = solid.into_cut_session();
    let mut latencies = Vec::new();
    for (i, normal) in [
        [0.0, 0.0, 1.0],
        [1.0, 2.0, 3.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ]
    .into_iter()
    .cycle()
    .take(8)
    .enumerate()
    {
        let spec = CutSpec {
            origin: [10.0 * i as f64, -7.0, 1000.0],
            normal,
            up: None,
            size: 128,
            spacing: 1.0,
        };
        let started = std::time::Instant::now();
        let image = session.cut(&spec)?;
        let ms = started.elapsed().as_secs_f64() * 1e3;
        latencies.push(ms);
        println!(
            "cut {i}: normal {normal:?}, {}x{} in {ms:.1} ms",
            image.width, image.height
        );
    }
    latencies.sort_by(f64::total_cmp);
    println!(
        "median {:.1} ms (the first cut builds the cache)",
        latencies[latencies.len() / 2]
    );
    Ok(())
}
