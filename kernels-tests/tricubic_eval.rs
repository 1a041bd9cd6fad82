//! `tricubic_eval`: GPU against the CPU reference on volumes, oblique slices and point lists.

use solidsynth::cpu::tricubic_eval::{tricubic_eval, Query};
use solidsynth::gradient::GradientSolid;
use solidsynth::util::hash::SeededRng;

/// Named tolerance: |gpu - cpu| <= TOLERANCE * scale, scale = 1 + 4 * max |control value| (the
/// size of the weighted terms, gradients scaled by the spacing). f32 sums of 32 products, with
/// cancellation; the shader compiler may fuse multiply-adds, so results are not bit-exact. With
/// colour data (scale ~ 1000) this is 0.1 of an 8-bit level.
const TOLERANCE: f32 = 1e-4;

fn close(what: &str, cpu: &[f32], gpu: &[f32], scale: f32) -> Result<(), String> {
    if cpu.len() != gpu.len() {
        return Err(format!("{what}: length {} vs {}", cpu.len(), gpu.len()));
    }
    let worst = cpu
        .iter()
        .zip(gpu)
        .map(|(c, g)| (c - g).abs() / scale)
        .fold(
            0f32,
            |m, e| if e.is_nan() { f32::INFINITY } else { m.max(e) },
        );
    if worst > TOLERANCE {
        return Err(format!("{what}: worst relative error {worst}"));
    }
    Ok(())
}

fn solid(channels: u32) -> GradientSolid {
    let mut s = GradientSolid::new([5, 4, 6], channels).unwrap();
    let mut rng = SeededRng::new(17);
    for v in s.data.iter_mut() {
        *v = rng.below(40_000) as f32 / 100.0 - 200.0;
    }
    s
}

#[test]
fn tricubic_eval_matches_its_reference() {
    let _serial = crate::serial();
    let Some(gpu) = crate::gpu() else { return };
    let s = solid(3);
    let r = 1.0 / 2f32.sqrt();
    let mut rng = SeededRng::new(3);
    let queries = [
        ("volume", Query::volume([17, 13, 21])),
        (
            "oblique slice",
            Query::Grid {
                origin: [1.5, 0.25, 2.0],
                a: [0.37 * r, 0.37 * r, 0.0],
                b: [0.0, 0.2, 0.45],
                c: [0.0; 3],
                n: [40, 50, 1],
            },
        ),
        (
            // Includes points outside the domain (clamped on both backends).
            "points",
            Query::Points(
                (0..3001)
                    .map(|_| [0; 3].map(|_| rng.below(30_000) as f32 / 1000.0 - 3.0))
                    .collect(),
            ),
        ),
    ];
    let scale = 1.0 + 4.0 * s.data.iter().fold(0f32, |m, v| m.max(v.abs()));
    for (what, q) in &queries {
        let cpu = tricubic_eval(&s, q);
        let out = solidsynth::gpu::tricubic_eval::tricubic_eval(gpu, &s, q).unwrap();
        close(what, &cpu, &out, scale).unwrap();
    }
    // Other channel counts.
    for channels in [1, 4, 16] {
        let s = solid(channels);
        let scale = 1.0 + 4.0 * s.data.iter().fold(0f32, |m, v| m.max(v.abs()));
        let q = Query::volume([9, 7, 11]);
        let cpu = tricubic_eval(&s, &q);
        let out = solidsynth::gpu::tricubic_eval::tricubic_eval(gpu, &s, &q).unwrap();
        close(&format!("{channels} channels"), &cpu, &out, scale).unwrap();
    }
    // The comparison fails on a perturbed result.
    let q = Query::volume([9, 9, 9]);
    let cpu = tricubic_eval(&s, &q);
    let mut bad = cpu.clone();
    bad[100] += 2.0 * TOLERANCE * scale;
    assert!(close("perturbed", &cpu, &bad, scale).is_err());
    bad[100] = f32::NAN;
    assert!(close("nan", &cpu, &bad, scale).is_err());
}

/// The kernel's 8-bit mode against the reference's: equal bytes, except a difference of one
/// level where the float value lies within the tolerance of a rounding boundary (x.5).
fn same_bytes(
    what: &str,
    floats: &[f32],
    cpu: &[u8],
    gpu: &[u8],
    scale: f32,
) -> Result<(), String> {
    if cpu.len() != gpu.len() {
        return Err(format!("{what}: length {} vs {}", cpu.len(), gpu.len()));
    }
    for (i, ((&c, &g), &f)) in cpu.iter().zip(gpu).zip(floats).enumerate() {
        let near_boundary = ((f - f.floor()) - 0.5).abs() <= TOLERANCE * scale;
        if c != g && !(near_boundary && c.abs_diff(g) == 1) {
            return Err(format!(
                "{what}: byte {i} is {g}, the reference {c} (value {f})"
            ));
        }
    }
    Ok(())
}

#[test]
fn tricubic_eval_u8_matches_its_reference() {
    use solidsynth::cpu::tricubic_eval::tricubic_eval_u8;
    let _serial = crate::serial();
    let Some(gpu) = crate::gpu() else { return };
    // Values around the 8-bit range, so that the clamps at 0 and 255 and the rounding are hit.
    let mut s = solid(3);
    for v in s.data.iter_mut() {
        *v = *v * 0.8 + 128.0;
    }
    let scale = 1.0 + 4.0 * s.data.iter().fold(0f32, |m, v| m.max(v.abs()));
    let oblique = Query::Grid {
        origin: [0.5, 1.25, -1.0],
        a: [0.3, 0.1, 0.05],
        b: [0.0, 0.25, 0.3],
        c: [0.0; 3],
        n: [37, 41, 1],
    };
    for (what, q) in [
        ("volume", Query::volume([17, 13, 21])),
        ("oblique slice", oblique),
    ] {
        let floats = tricubic_eval(&s, &q);
        let cpu = tricubic_eval_u8(&s, &q);
        let out = solidsynth::gpu::tricubic_eval::tricubic_eval_u8(gpu, &s, &q).unwrap();
        same_bytes(what, &floats, &cpu, &out, scale).unwrap();
        assert!(
            cpu.contains(&0) && cpu.contains(&255),
            "{what}: clamps not exercised"
        );
    }
    for channels in [1, 2, 4] {
        let mut s = solid(channels);
        s.data.iter_mut().for_each(|v| *v = *v * 0.5 + 100.0);
        let q = Query::volume([9, 7, 11]);
        let floats = tricubic_eval(&s, &q);
        let cpu = tricubic_eval_u8(&s, &q);
        let out = solidsynth::gpu::tricubic_eval::tricubic_eval_u8(gpu, &s, &q).unwrap();
        same_bytes(&format!("{channels} channels"), &floats, &cpu, &out, scale).unwrap();
    }
    // Cell-mode volumes split over many dispatches (a small binding limit: chunks of 4 or 8 z
    // slices, the last one partial), and a layer too large for one binding (the general path).
    let mut opts = solidsynth::gpu::GpuOptions::from_env();
    opts.max_binding_bytes = Some(17 * 13 * 4 * 8);
    let small = crate::open(opts).expect("adapter");
    let q = Query::volume([17, 13, 21]);
    let floats = tricubic_eval(&s, &q);
    let out = solidsynth::gpu::tricubic_eval::tricubic_eval_u8(&small, &s, &q).unwrap();
    same_bytes(
        "chunked u8",
        &floats,
        &tricubic_eval_u8(&s, &q),
        &out,
        scale,
    )
    .unwrap();
    let out = solidsynth::gpu::tricubic_eval::tricubic_eval(&small, &s, &q).unwrap();
    close("chunked f32 (general path)", &floats, &out, scale).unwrap();
    let mut opts = solidsynth::gpu::GpuOptions::from_env();
    opts.max_binding_bytes = Some(17 * 13 * 4 * 3 * 4);
    let small = crate::open(opts).expect("adapter");
    let out = solidsynth::gpu::tricubic_eval::tricubic_eval(&small, &s, &q).unwrap();
    close("chunked f32", &floats, &out, scale).unwrap();
    // More than 4 channels do not fit a word: refused, not truncated.
    assert!(solidsynth::gpu::tricubic_eval::tricubic_eval_u8(
        gpu,
        &solid(5),
        &Query::volume([2; 3])
    )
    .is_err());
    // The comparison fails on a changed byte away from a boundary.
    let q = Query::volume([9, 9, 9]);
    let floats = tricubic_eval(&s, &q);
    let cpu = tricubic_eval_u8(&s, &q);
    let i = floats
        .iter()
        .position(|f| ((f - f.floor()) - 0.5).abs() > 0.1 && (1.0..254.0).contains(f))
        .unwrap();
    let mut bad = cpu.clone();
    bad[i] += 1;
    assert!(same_bytes("perturbed", &floats, &cpu, &bad, scale).is_err());
}

#[test]
fn region_solids_evaluate_the_same_on_both_backends() {
    use solidsynth::backend::Compute;
    use solidsynth::gradient::regions::{vectorize_regions, Blend};
    use solidsynth::volume::Volume;
    let _serial = crate::serial();
    let Some(gpu) = crate::gpu() else { return };
    let n = 17u32;
    let (mut v, mut m) = (Volume::new(n, n, n, 3), Volume::new(n, n, n, 1));
    let mut rng = SeededRng::new(4);
    for i in 0..(n * n * n) as usize {
        let inside = rng.below(3) == 0 || (i % 17) < 6;
        m.data[i] = if inside { 255 } else { 0 };
        for c in 0..3 {
            v.data[i * 3 + c] = rng.below(256) as u8;
        }
    }
    let rs = vectorize_regions(&v, &m, "mask").unwrap();
    let query = Query::Grid {
        origin: [0.3, -1.0, 2.2],
        a: [0.8, 0.1, 0.0],
        b: [0.0, 0.7, 0.3],
        c: [0.1, 0.0, 0.9],
        n: [19, 18, 17],
    };
    let ctx = std::sync::Arc::new(
        crate::open(solidsynth::gpu::GpuOptions::from_env()).expect("the adapter opened before"),
    );
    let scale = 1.0
        + 4.0
            * [&rs.positive, &rs.negative]
                .iter()
                .flat_map(|s| s.data.iter())
                .fold(0f32, |m, x| m.max(x.abs()));
    for blend in [Blend::Exact, Blend::Antialiased] {
        let cpu = rs.eval_query(&query, &Compute::Cpu, blend).unwrap();
        let g = rs
            .eval_query(&query, &Compute::Gpu(ctx.clone()), blend)
            .unwrap();
        // Near the boundary a sign decided on a distance within the tolerance of 0 may differ:
        // allow those samples only.
        let d = tricubic_eval(&rs.distance, &query);
        let c = 3;
        let mut checked = 0;
        for (k, &dk) in d.iter().enumerate() {
            if dk.abs() < 1e-3 {
                continue;
            }
            close(
                &format!("{blend:?} sample {k}"),
                &cpu[k * c..(k + 1) * c],
                &g[k * c..(k + 1) * c],
                scale,
            )
            .unwrap();
            checked += 1;
        }
        assert!(checked > 5000, "{checked}");
    }
    let _ = gpu;
}
