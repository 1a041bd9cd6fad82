//! The orthonormal 2D Legendre basis of the paper's section VI. The PTM basis
//! A = {lu^2, lv^2, lu lv, lu, lv, 1} is not orthogonal, so distances between coefficient vectors
//! are not distances between reflectance functions. Over [-1, 1]^2 the basis
//!
//!   B = {1/2, (sqrt3/2) lu, (sqrt3/2) lv, (3/2) lu lv, (sqrt45/4) lu^2 - sqrt45/12,
//!        (sqrt45/4) lv^2 - sqrt45/12}
//!
//! is orthonormal (products of the normalized 1D Legendre polynomials sqrt(1/2), sqrt(3/2) x,
//! sqrt(5/2) (3x^2 - 1)/2), so for b = M a, |b1 - b2|^2 = integral over [-1,1]^2 of (g1 - g2)^2.
//! The paper defers M to a technical report; it is derived here by writing each A function in B:
//!   1 = 2 B0,  lu = (2/sqrt3) B1,  lv = (2/sqrt3) B2,  lu lv = (2/3) B3,
//!   lu^2 = (4/sqrt45) B4 + (2/3) B0,  lv^2 = (4/sqrt45) B5 + (2/3) B0.
//! (The basis in the extracted paper text reads correctly; tested numerically below and in
//! tests/ptm/searches.rs.)

const SQRT3: f64 = 1.732_050_807_568_877_2;
const SQRT45: f64 = 6.708_203_932_499_369;

/// PTM coefficients a (a0 lu^2 + a1 lv^2 + a2 lu lv + a3 lu + a4 lv + a5) to Legendre
/// coefficients b (in the order of B above).
pub fn to_legendre(a: &[f64; 6]) -> [f64; 6] {
    [
        2.0 * a[5] + (2.0 / 3.0) * (a[0] + a[1]),
        (2.0 / SQRT3) * a[3],
        (2.0 / SQRT3) * a[4],
        (2.0 / 3.0) * a[2],
        (4.0 / SQRT45) * a[0],
        (4.0 / SQRT45) * a[1],
    ]
}

/// The inverse of [`to_legendre`].
pub fn from_legendre(b: &[f64; 6]) -> [f64; 6] {
    let a0 = SQRT45 / 4.0 * b[4];
    let a1 = SQRT45 / 4.0 * b[5];
    [
        a0,
        a1,
        1.5 * b[3],
        SQRT3 / 2.0 * b[1],
        SQRT3 / 2.0 * b[2],
        (b[0] - (2.0 / 3.0) * (a0 + a1)) / 2.0,
    ]
}

/// The matrix M of b = M a (rows: b index), e.g. for documentation and tests.
pub fn matrix() -> [[f64; 6]; 6] {
    let mut m = [[0.0; 6]; 6];
    for j in 0..6 {
        let mut e = [0.0; 6];
        e[j] = 1.0;
        let col = to_legendre(&e);
        for i in 0..6 {
            m[i][j] = col[i];
        }
    }
    m
}

/// The L2 distance squared between two PTM functions over [-1, 1]^2, by Gauss-Legendre
/// quadrature (exact for these degree-4 integrands with 3 nodes per axis).
pub fn function_distance_sq(a1: &[f64; 6], a2: &[f64; 6]) -> f64 {
    let nodes = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
    let weights = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    let mut sum = 0.0;
    for (u, wu) in nodes.iter().zip(weights) {
        for (v, wv) in nodes.iter().zip(weights) {
            let g = |a: &[f64; 6]| {
                a[0] * u * u + a[1] * v * v + a[2] * u * v + a[3] * u + a[4] * v + a[5]
            };
            let d = g(a1) - g(a2);
            sum += wu * wv * d * d;
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legendre_round_trip_and_distance_preservation() {
        let a1 = [0.3, -0.2, 0.11, 0.5, -0.7, 0.25];
        let a2 = [-0.1, 0.4, -0.3, 0.05, 0.2, 0.6];
        let back = from_legendre(&to_legendre(&a1));
        for i in 0..6 {
            assert!((back[i] - a1[i]).abs() < 1e-12);
        }
        let (b1, b2) = (to_legendre(&a1), to_legendre(&a2));
        let coeff: f64 = (0..6).map(|i| (b1[i] - b2[i]).powi(2)).sum();
        let raw: f64 = (0..6).map(|i| (a1[i] - a2[i]).powi(2)).sum();
        let f = function_distance_sq(&a1, &a2);
        assert!((coeff - f).abs() < 1e-12 * f.max(1.0), "{coeff} vs {f}");
        // The raw PTM coefficients do not preserve it (the reason for the transform).
        assert!((raw - f).abs() > 1e-3);
    }
}
