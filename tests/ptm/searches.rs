//! The Legendre basis and the exact projection search against brute force.

use super::*;

#[test]
fn legendre_distances_are_reflectance_function_distances() {
    let mut rng = SeededRng::new(9);
    let m = legendre::matrix();
    // The constant 1 is 2 B0 (B0 = 1/2).
    assert!((m[0][5] - 2.0).abs() < 1e-12);
    for _ in 0..500 {
        let mut r = || rng.below(2_000_001) as f64 / 1e6 - 1.0;
        let a1 = [r(), r(), r(), r(), r(), r()];
        let a2 = [r(), r(), r(), r(), r(), r()];
        let (b1, b2) = (legendre::to_legendre(&a1), legendre::to_legendre(&a2));
        let coeff: f64 = (0..6).map(|i| (b1[i] - b2[i]).powi(2)).sum();
        // Independent check: a fine midpoint rule over [-1, 1]^2.
        let n = 200;
        let mut f = 0.0;
        for i in 0..n {
            for j in 0..n {
                let (u, v) = (
                    -1.0 + (i as f64 + 0.5) * 2.0 / n as f64,
                    -1.0 + (j as f64 + 0.5) * 2.0 / n as f64,
                );
                let g = |a: &[f64; 6]| {
                    a[0] * u * u + a[1] * v * v + a[2] * u * v + a[3] * u + a[4] * v + a[5]
                };
                f += (g(&a1) - g(&a2)).powi(2) * (2.0 / n as f64).powi(2);
            }
        }
        assert!((coeff - f).abs() < 1e-3 * f.max(1e-3), "{coeff} vs {f}");
        let back = legendre::from_legendre(&b1);
        assert!((0..6).all(|i| (back[i] - a1[i]).abs() < 1e-12));
    }
}

#[test]
fn projection_search_equals_brute_force_on_many_queries() {
    for (format, block, overlap) in [
        (PtmFormat::Lrgb, 12, 3),
        (PtmFormat::Rgb, 10, 4),
        (PtmFormat::Lrgb, 16, 6),
    ] {
        let src = search::features(&source(40, format, 7));
        let searcher = Searcher::new(src.clone(), block, overlap);
        let q = query_image(&src, format, 64, 64, 11);
        let mut rng = SeededRng::new(1);
        let mut stats = SearchStats::default();
        for k in 0..60 {
            let (qx, qy) = (
                rng.below((64 - block) as u64) as u32,
                rng.below((64 - block) as u64) as u32,
            );
            let shape = [Shape::Left, Shape::Top, Shape::Both][k % 3];
            for permille in [0, 100, 500] {
                let tol = Tolerance { permille };
                let brute = searcher.brute(&q, qx, qy, shape, tol);
                let hints = [rng.below(searcher.candidates() as u64) as u32];
                let proj =
                    searcher.projection(&q, qx, qy, shape, tol, &hints[..(k % 2)], &mut stats);
                assert_eq!(
                    brute, proj,
                    "{format:?} query {k} at ({qx}, {qy}) {shape:?} tol {permille}"
                );
                assert!(!brute.within.is_empty());
            }
        }
        // Queries copied from the source have distance 0 at their own position (ties: all the
        // zero-distance candidates, smallest index first).
        for k in 0..20 {
            let (sx, sy) = (
                rng.below(searcher.cand_w as u64) as u32,
                rng.below(searcher.cand_h as u64) as u32,
            );
            let m = searcher.projection(
                &src,
                sx,
                sy,
                [Shape::Left, Shape::Top, Shape::Both][k % 3],
                Tolerance { permille: 0 },
                &[],
                &mut stats,
            );
            assert_eq!(m.best, 0);
            assert!(m
                .within
                .iter()
                .any(|&(i, _)| searcher.origin(i) == (sx, sy)));
            assert_eq!(
                m,
                searcher.brute(
                    &src,
                    sx,
                    sy,
                    [Shape::Left, Shape::Top, Shape::Both][k % 3],
                    Tolerance { permille: 0 }
                )
            );
        }
    }
}
