//! Quilting (seeded, identical across searches and threads, blending, RGB) and relighting.

use super::*;

#[test]
fn quilting_is_seeded_identical_across_searches_and_threads() {
    let src = source(48, PtmFormat::Lrgb, 5);
    let mut p = QuiltParams::new(80);
    p.block = 16;
    p.overlap = 4;
    p.seed = 3;
    let (a, ra) = quilt::synthesize(&src, &p, &mut |_, _| {}).unwrap();
    assert_eq!((a.width, a.height), (80, 80));
    let mut brute = p.clone();
    brute.search = SearchMethod::Brute;
    let (b, rb) = quilt::synthesize(&src, &brute, &mut |_, _| {}).unwrap();
    assert_eq!(ra.choices, rb.choices);
    assert!(a == b, "projection and brute force outputs differ");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let (c, _) = one.install(|| quilt::synthesize(&src, &p, &mut |_, _| {}).unwrap());
    assert!(a == c, "output depends on the thread count");
    p.seed = 4;
    let (d, _) = quilt::synthesize(&src, &p, &mut |_, _| {}).unwrap();
    assert!(a != d, "the seed changes nothing");
    // With cuts every output texel is a source texel.
    let texels: std::collections::HashSet<&[u8]> = src.texels.chunks(9).collect();
    assert!(a.texels.chunks(9).all(|t| texels.contains(t)));
    // Not a verbatim copy: blocks come from several places, and neighbours overlap consistently
    // (the cut's seam error is far below that of random placement).
    let distinct: std::collections::HashSet<u32> = ra.choices.iter().copied().collect();
    assert!(distinct.len() > ra.choices.len() / 2, "{:?}", ra.choices);
}

#[test]
fn blending_and_rgb_quilting_work() {
    let src = source(40, PtmFormat::Rgb, 6);
    let mut p = QuiltParams::new(64);
    p.block = 12;
    p.overlap = 4;
    p.boundary = Boundary::Blend;
    let (a, _) = quilt::synthesize(&src, &p, &mut |_, _| {}).unwrap();
    let (b, _) = quilt::synthesize(&src, &p, &mut |_, _| {}).unwrap();
    assert!(a == b);
    assert_eq!(a.texels.len(), 64 * 64 * 18);
    // Blended texels exist (not in the source).
    let texels: std::collections::HashSet<&[u8]> = src.texels.chunks(18).collect();
    assert!(a.texels.chunks(18).any(|t| !texels.contains(t)));
    for bad in [(2, 1), (50, 6), (12, 0), (12, 7)] {
        let mut q = p.clone();
        (q.block, q.overlap) = bad;
        let e = quilt::synthesize(&src, &q, &mut |_, _| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("--block") || e.contains("--overlap"), "{e}");
    }
    // A source smaller than the smallest block is named as the problem, not the block.
    let e = quilt::synthesize(&source(3, PtmFormat::Rgb, 6), &p, &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("the source PTM: is a 3x3 PTM"), "{e}");
}

#[test]
fn relighting_follows_the_light() {
    let cap = capture::synthetic(48, 20, 8);
    let ptm = fit::fit(&cap, PtmFormat::Lrgb, "c").unwrap();
    // Relit at a captured light, the PTM is close to that photograph, closer than to the
    // photograph under the most different light.
    let diff = |img: &image::RgbImage, rgb: &[f32]| -> f64 {
        let s: f64 = img
            .pixels()
            .enumerate()
            .map(|(i, p)| {
                (0..3)
                    .map(|c| {
                        ((rgb[3 * i + c] * 255.0).clamp(0.0, 255.0) as f64 - p.0[c] as f64).powi(2)
                    })
                    .sum::<f64>()
            })
            .sum();
        (s / (img.len() as f64)).sqrt()
    };
    for k in [2usize, 9, 17] {
        let l = cap.lights[k];
        let rgb = ptm_relight(
            &ptm,
            &Lighting {
                lu: l.lu as f32,
                lv: l.lv as f32,
                specular: 0.0,
            },
        );
        let far = (0..cap.lights.len())
            .max_by(|&a, &b| {
                let d = |j: usize| {
                    (cap.lights[j].lu - l.lu).powi(2) + (cap.lights[j].lv - l.lv).powi(2)
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        let (near_err, far_err) = (diff(&cap.images[k], &rgb), diff(&cap.images[far], &rgb));
        assert!(
            near_err * 2.0 < far_err,
            "light {k}: {near_err} vs {far_err}"
        );
    }
    // A specular term only adds light.
    let plain = ptm_relight(
        &ptm,
        &Lighting {
            lu: 0.3,
            lv: 0.1,
            specular: 0.0,
        },
    );
    let shiny = ptm_relight(
        &ptm,
        &Lighting {
            lu: 0.3,
            lv: 0.1,
            specular: 0.5,
        },
    );
    assert!(plain.iter().zip(&shiny).all(|(a, b)| b >= a));
    assert!(plain.iter().zip(&shiny).any(|(a, b)| b - a > 0.05));
}
