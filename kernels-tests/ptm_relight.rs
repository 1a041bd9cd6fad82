//! `ptm_relight`: GPU against the CPU reference on LRGB and RGB maps, several lights, with and
//! without the specular term, across chunk boundaries.

use solidsynth::cpu::ptm_relight::{ptm_relight, Lighting};
use solidsynth::ptm::{Ptm, PtmFormat};
use solidsynth::util::hash::SeededRng;

/// Named tolerance, absolute, on unit-intensity values, times (1 + specular): f32 evaluation of
/// a 6-term polynomial with coefficients of magnitude <= ~4; the shader compiler may fuse
/// multiply-adds, and division and sqrt are not correctly rounded on every device (WGSL allows
/// 2.5 ULP), which the highlight's 32nd power amplifies 32-fold. 2e-4 is 1/20 of an 8-bit level.
const TOLERANCE: f32 = 2e-4;

fn close(what: &str, cpu: &[f32], gpu: &[f32], specular: f32) -> Result<(), String> {
    if cpu.len() != gpu.len() {
        return Err(format!("{what}: length {} vs {}", cpu.len(), gpu.len()));
    }
    let (mut worst, mut at) = (0f32, 0);
    for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
        let e = (c - g).abs();
        let e = if e.is_nan() { f32::INFINITY } else { e };
        if e > worst {
            (worst, at) = (e, i);
        }
    }
    if worst > TOLERANCE * (1.0 + specular) {
        return Err(format!(
            "{what}: worst error {worst} at word {at} (cpu {} gpu {})",
            cpu[at], gpu[at]
        ));
    }
    Ok(())
}

/// A map of random texels with a plausible scale and bias (coefficients within about +-2).
fn random_ptm(format: PtmFormat, w: u32, h: u32, seed: u64) -> Ptm {
    let mut rng = SeededRng::new(seed);
    let texels = (0..w as usize * h as usize * format.texel_bytes())
        .map(|_| rng.below(256) as u8)
        .collect();
    Ptm {
        format,
        width: w,
        height: h,
        scale: [2.0, 1.75, 1.5, 2.25, 2.0, 1.25],
        bias: [128, 120, 130, 127, 126, 40],
        texels,
    }
}

#[test]
fn ptm_relight_matches_its_reference() {
    let _serial = crate::serial();
    let Some(gpu) = crate::gpu() else { return };
    for (format, seed) in [(PtmFormat::Lrgb, 1), (PtmFormat::Rgb, 2)] {
        let ptm = random_ptm(format, 67, 45, seed);
        for (lu, lv, specular) in [
            (0.0, 0.0, 0.0),
            (0.6, -0.3, 0.0),
            (-0.2, 0.9, 0.7),
            (0.7, 0.7, 1.5),
        ] {
            let light = Lighting { lu, lv, specular };
            let cpu = ptm_relight(&ptm, &light);
            let out = solidsynth::gpu::ptm_relight::ptm_relight(gpu, &ptm, &light).unwrap();
            close(&format!("{format:?} {light:?}"), &cpu, &out, specular).unwrap();
        }
    }
    // Small binding limit: many chunks, each starting on a word boundary.
    let mut opts = solidsynth::gpu::GpuOptions::from_env();
    opts.max_binding_bytes = Some(4096);
    let small = crate::open(opts).expect("adapter");
    let ptm = random_ptm(PtmFormat::Lrgb, 50, 31, 3);
    let light = Lighting {
        lu: 0.3,
        lv: 0.2,
        specular: 0.4,
    };
    let out = solidsynth::gpu::ptm_relight::ptm_relight(&small, &ptm, &light).unwrap();
    close("chunked", &ptm_relight(&ptm, &light), &out, 0.4).unwrap();
    // The comparison fails on a perturbed result and on a never-written (sentinel NaN) value.
    let cpu = ptm_relight(&ptm, &light);
    let mut bad = cpu.clone();
    bad[77] += 3.0 * TOLERANCE * 1.4;
    assert!(close("perturbed", &cpu, &bad, 0.4).is_err());
    bad[77] = f32::from_bits(0x7FC0_DEAD);
    assert!(close("sentinel", &cpu, &bad, 0.4).is_err());
}
