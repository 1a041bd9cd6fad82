//! Instant editing of a gradient solid (paper 4.4, after Li, Ju and Hu 2010): strokes with
//! strengths give an influence field h, a sum of RBFs centred on the strokes (eq. 4) whose
//! non-negative weights are fitted to the strengths (non-negative least squares); every control
//! point then moves towards a reference colour, c' = (1 - h) c + h c_ref, its gradient updated
//! analytically (eqs. 5 and 6). No voxel is touched: the cost is one pass over the control points.
//!
//! Choices where the paper is silent: the RBF centres are the strokes themselves (at most
//! [`MAX_CENTRES`], evenly subsampled); a stroke's colour is the solid at its position; h is
//! clamped to [0, 1] (its gradient is zero where clamped); colour terms use the first
//! min(3, channels) channels, and every channel is blended.

use super::GradientSolid;
use crate::error::{Error, Result};

/// Propagation parameters of eq. 4: the paper's defaults (colours in 0..255 units, positions in
/// voxels). A larger alpha makes an edit more local in both space and colour; a larger beta
/// weighs distance more than colour.
pub const ALPHA: f64 = 1e-4;
pub const BETA: f64 = 0.1;

/// The parameters of an edit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Propagation {
    pub alpha: f64,
    pub beta: f64,
}

impl Default for Propagation {
    fn default() -> Self {
        Propagation {
            alpha: ALPHA,
            beta: BETA,
        }
    }
}
/// Most RBF centres used.
pub const MAX_CENTRES: usize = 256;

/// The most strokes a file may hold: the fit's matrix is then 200 MiB (a row of
/// [`MAX_CENTRES`] f64 per stroke).
pub const MAX_STROKES: usize = 100_000;

#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stroke {
    pub position: [f64; 3],
    pub strength: f64,
}

#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Strokes {
    pub strokes: Vec<Stroke>,
}

/// Parse and check a strokes JSON file (`name` labels errors).
pub fn parse_strokes(text: &str, name: &str) -> Result<Vec<Stroke>> {
    let s: Strokes = serde_json::from_str(text).map_err(|e| {
        Error::invalid(name, format!("expected {{\"strokes\": [{{\"position\": [x, y, z], \"strength\": s}}, ...]}}: {e}"))
    })?;
    check_strokes(&s.strokes, name)?;
    Ok(s.strokes)
}

/// Refuse strokes no fit can use: none, more than [`MAX_STROKES`], a position that is not
/// finite, a strength outside [0, 1]. `name` labels errors.
pub fn check_strokes(strokes: &[Stroke], name: &str) -> Result<()> {
    if strokes.is_empty() {
        return Err(Error::invalid(name, "no strokes"));
    }
    if strokes.len() > MAX_STROKES {
        return Err(Error::invalid(
            name,
            format!(
                "holds {} strokes; at most {MAX_STROKES} are fitted (each adds a row of \
                 {MAX_CENTRES} kernel values to the fit)",
                strokes.len()
            ),
        ));
    }
    for (i, k) in strokes.iter().enumerate() {
        if !k.position.iter().all(|v| v.is_finite()) {
            return Err(Error::invalid(
                name,
                format!("stroke {i}: position must be finite"),
            ));
        }
        if !(0.0..=1.0).contains(&k.strength) {
            return Err(Error::invalid(
                name,
                format!("stroke {i}: strength must be in [0, 1]"),
            ));
        }
    }
    Ok(())
}

struct Centre {
    position: [f64; 3],
    color: Vec<f64>,
}

/// Squared colour distance over the colour channels.
fn color_d2(a: &[f64], b: &[f64], n: usize) -> f64 {
    (0..n).map(|c| (a[c] - b[c]).powi(2)).sum()
}

/// The fitted influence field h (eq. 4).
pub struct Influence {
    centres: Vec<Centre>,
    weights: Vec<f64>,
    colour_channels: usize,
    propagation: Propagation,
    /// A periodic solid's period: distances to the strokes are taken to their nearest copies,
    /// so the edit repeats with the solid and it stays periodic.
    period: Option<[f64; 3]>,
    /// RMS difference between h at the strokes and their strengths.
    pub residual: f64,
}

impl Influence {
    /// Fit weights >= 0 so that h at each stroke matches its strength.
    pub fn fit(solid: &GradientSolid, strokes: &[Stroke], propagation: Propagation) -> Influence {
        let channels = solid.channels as usize;
        let eval = |p: [f64; 3]| {
            let mut out = vec![0f32; channels];
            solid.eval(p.map(|v| v as f32), &mut out);
            out.into_iter().map(|v| v as f64).collect::<Vec<f64>>()
        };
        let period = solid.periodic.then(|| solid.size.map(f64::from));
        // A stroke on a periodic solid stands for all its copies: read its colour in the period.
        let at = |p: [f64; 3]| match period {
            Some(period) => std::array::from_fn(|a| p[a].rem_euclid(period[a])),
            None => p,
        };
        let step = strokes.len().div_ceil(MAX_CENTRES);
        let mut inf = Influence {
            centres: strokes
                .iter()
                .step_by(step)
                .map(|s| Centre {
                    position: s.position,
                    color: eval(at(s.position)),
                })
                .collect(),
            weights: Vec::new(),
            colour_channels: channels.min(3),
            propagation,
            period,
            residual: 0.0,
        };
        let mut a = ndarray::Array2::<f64>::zeros((strokes.len(), inf.centres.len()));
        let mut b = ndarray::Array1::<f64>::zeros(strokes.len());
        for (j, s) in strokes.iter().enumerate() {
            let c = eval(at(s.position));
            for (k, centre) in inf.centres.iter().enumerate() {
                a[[j, k]] = inf.kernel(s.position, &c, centre);
            }
            b[j] = s.strength;
        }
        let (w, residual) = nnls::nnls(a.view(), b.view());
        inf.weights = w.to_vec();
        inf.residual = residual / (strokes.len() as f64).sqrt();
        inf
    }

    /// p - q along `axis`; for a periodic solid, to q's nearest copy, in [-P/2, P/2) (the same
    /// for p and p + P, so the first and last faces of control points stay equal).
    fn offset(&self, p: [f64; 3], q: [f64; 3], axis: usize) -> f64 {
        let d = p[axis] - q[axis];
        match self.period {
            Some(period) => (d + period[axis] / 2.0).rem_euclid(period[axis]) - period[axis] / 2.0,
            None => d,
        }
    }

    fn kernel(&self, p: [f64; 3], c: &[f64], k: &Centre) -> f64 {
        let dp: f64 = (0..3).map(|i| self.offset(p, k.position, i).powi(2)).sum();
        let Propagation { alpha, beta } = self.propagation;
        (-alpha * (beta * dp + color_d2(c, &k.color, self.colour_channels))).exp()
    }

    /// h at position p for colour c (eq. 4), clamped to [0, 1].
    pub fn h(&self, p: [f64; 3], c: &[f64]) -> f64 {
        let h: f64 = self
            .centres
            .iter()
            .zip(&self.weights)
            .map(|(k, w)| w * self.kernel(p, c, k))
            .sum();
        h.clamp(0.0, 1.0)
    }

    /// h and its derivative along the solid (eq. 6) at p, colour c, colour gradients `grad`.
    fn h_and_gradient(&self, p: [f64; 3], c: &[f64], grad: &[[f64; 3]]) -> (f64, [f64; 3]) {
        let mut h = 0.0;
        let mut dh = [0f64; 3];
        for (centre, &wk) in self.centres.iter().zip(&self.weights) {
            if wk == 0.0 {
                continue;
            }
            let hk = self.kernel(p, c, centre);
            h += wk * hk;
            for axis in 0..3 {
                // beta (p - p_k) + (dc/dp)^T (c - c_k), over the colour channels.
                let colour_term: f64 = (0..self.colour_channels)
                    .map(|ch| grad[ch][axis] * (c[ch] - centre.color[ch]))
                    .sum();
                let Propagation { alpha, beta } = self.propagation;
                dh[axis] -= wk
                    * 2.0
                    * alpha
                    * hk
                    * (beta * self.offset(p, centre.position, axis) + colour_term);
            }
        }
        if !(0.0..=1.0).contains(&h) {
            return (h.clamp(0.0, 1.0), [0.0; 3]);
        }
        (h, dh)
    }
}

/// Apply an edit in place (eqs. 4-6 at every control point); returns the fit's residual (RMS
/// over strokes of h - strength).
pub fn edit(
    solid: &mut GradientSolid,
    strokes: &[Stroke],
    reference: &[f64],
    propagation: Propagation,
) -> Result<f64> {
    let alpha_ok = propagation.alpha > 0.0 && propagation.alpha.is_finite();
    let beta_ok = propagation.beta >= 0.0 && propagation.beta.is_finite();
    if !(alpha_ok && beta_ok) {
        return Err(Error::invalid(
            "--alpha/--beta",
            "alpha must be positive and beta non-negative (finite numbers)",
        ));
    }
    check_strokes(strokes, "strokes")?;
    let channels = solid.channels as usize;
    if reference.len() != channels || !reference.iter().all(|c| c.is_finite()) {
        return Err(Error::invalid(
            "--color",
            format!("needs {channels} finite components for this solid"),
        ));
    }
    let inf = Influence::fit(solid, strokes, propagation);
    let d = super::SPACING as f64;
    let dims = solid.dims;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = [i as f64 * d, j as f64 * d, k as f64 * d];
                let c: Vec<f64> = (0..channels)
                    .map(|ch| solid.at([i, j, k], ch as u32)[0] as f64)
                    .collect();
                let grad: Vec<[f64; 3]> = (0..channels)
                    .map(|ch| {
                        let v = solid.at([i, j, k], ch as u32);
                        [v[1] as f64, v[2] as f64, v[3] as f64]
                    })
                    .collect();
                let (h, dh) = inf.h_and_gradient(p, &c, &grad);
                for ch in 0..channels {
                    let v = solid.at_mut([i, j, k], ch as u32);
                    v[0] = ((1.0 - h) * c[ch] + h * reference[ch]) as f32;
                    for axis in 0..3 {
                        // Eq. 5.
                        v[1 + axis] = ((1.0 - h) * grad[ch][axis]
                            - (c[ch] - reference[ch]) * dh[axis])
                            as f32;
                    }
                }
            }
        }
    }
    Ok(inf.residual)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strokes_with_unknown_fields_are_refused() {
        let ok = r#"{"strokes": [{"position": [1, 2, 3], "strength": 0.5}]}"#;
        assert_eq!(parse_strokes(ok, "s.json").unwrap().len(), 1);
        for bad in [
            r#"{"strokes": [{"position": [1, 2, 3], "strength": 0.5, "radius": 4}]}"#,
            r#"{"strokes": [{"position": [1, 2, 3], "strength": 0.5}], "colour": 1}"#,
        ] {
            let err = parse_strokes(bad, "s.json").unwrap_err().to_string();
            assert!(
                err.contains("s.json") && err.contains("unknown field"),
                "{err}"
            );
        }
        let stroke = r#"{"position": [1, 2, 3], "strength": 0.5}"#;
        let many = format!(
            r#"{{"strokes": [{}]}}"#,
            [stroke; MAX_STROKES + 1].join(",")
        );
        let err = parse_strokes(&many, "s.json").unwrap_err().to_string();
        assert!(
            err.contains("holds 100001 strokes; at most 100000"),
            "{err}"
        );
    }

    /// Two regions of different colour: a full-strength stroke in one turns it (near the stroke)
    /// to the reference colour; the other region, far in colour, is untouched.
    #[test]
    fn strokes_recolour_similar_voxels_only() {
        let mut s = GradientSolid::new([9, 3, 3], 3).unwrap();
        for i in 0..9 {
            for j in 0..3 {
                for k in 0..3 {
                    let colour = if i < 4 {
                        [200.0, 40.0, 40.0]
                    } else {
                        [30.0, 30.0, 200.0]
                    };
                    for (ch, v) in colour.iter().enumerate() {
                        s.at_mut([i, j, k], ch as u32)[0] = *v;
                    }
                }
            }
        }
        let strokes = parse_strokes(
            r#"{"strokes": [{"position": [4, 4, 4], "strength": 1.0}, {"position": [8, 2, 6], "strength": 1.0}]}"#,
            "s",
        )
        .unwrap();
        let before = s.clone();
        let rms = edit(&mut s, &strokes, &[0.0, 255.0, 0.0], Propagation::default()).unwrap();
        assert!(rms < 0.05, "fit residual {rms}");
        let mut out = [0f32; 3];
        s.eval([4.0, 4.0, 4.0], &mut out);
        assert!(out[1] > 200.0 && out[0] < 60.0, "stroked voxel {out:?}");
        // The blue region (colour distance ~ 230) keeps its colour.
        for i in 5..9 {
            let (a, b) = (before.at([i, 1, 1], 2)[0], s.at([i, 1, 1], 2)[0]);
            assert!((a - b).abs() < 1.0, "point {i}: {a} -> {b}");
        }
    }

    /// A periodic solid stays periodic: a stroke near one face reaches the opposite face through
    /// its copy, so the last face of control points still equals the first.
    #[test]
    fn an_edit_of_a_periodic_solid_repeats_with_it() {
        let mut s = GradientSolid::new([5, 5, 5], 3).unwrap();
        let mut rng = crate::util::hash::SeededRng::new(3);
        for v in s.data.chunks_mut(4) {
            v[0] = 100.0 + rng.below(60) as f32;
        }
        // The last face a copy of the first, as synthesis writes it.
        for k in 0..5 {
            for j in 0..5 {
                for ch in 0..3 {
                    let first = s.at([0, j, k], ch).to_vec();
                    s.at_mut([4, j, k], ch).copy_from_slice(&first);
                }
            }
        }
        let mut s = s.into_periodic();
        let strokes = parse_strokes(
            r#"{"strokes": [{"position": [15.5, 8, 8], "strength": 1.0}]}"#,
            "s",
        )
        .unwrap();
        let propagation = Propagation {
            alpha: 1e-3,
            beta: 1.0,
        };
        edit(&mut s, &strokes, &[0.0, 255.0, 0.0], propagation).unwrap();
        for k in 0..5 {
            for j in 0..5 {
                for ch in 0..3 {
                    assert_eq!(s.at([0, j, k], ch), s.at([4, j, k], ch), "{j},{k},{ch}");
                }
            }
        }
        // The stroke at x = 15.5 reached x = 0 (half a voxel away through the period).
        let mut out = [0f32; 3];
        s.eval([0.0, 8.0, 8.0], &mut out);
        assert!(out[1] > 200.0, "{out:?}");
    }

    /// Eqs. 5-6 are the derivative of c'(p) = (1 - h(p, c(p))) c(p) + h c_ref along the original
    /// solid: compare the stored gradients with central differences of that function.
    #[test]
    fn updated_gradients_are_the_derivative_of_the_blend() {
        let mut s = GradientSolid::new([4, 4, 4], 3).unwrap();
        let mut rng = crate::util::hash::SeededRng::new(8);
        for v in s.data.chunks_mut(4) {
            v[0] = 100.0 + rng.below(60) as f32;
            for g in &mut v[1..] {
                *g = rng.below(200) as f32 / 10.0 - 10.0;
            }
        }
        let before = s.clone();
        let strokes = parse_strokes(
            r#"{"strokes": [{"position": [5, 6, 4], "strength": 0.7}, {"position": [9, 2, 7], "strength": 0.4}]}"#,
            "s",
        )
        .unwrap();
        let reference = [10.0, 220.0, 60.0];
        let inf = Influence::fit(&before, &strokes, Propagation::default());
        edit(&mut s, &strokes, &reference, Propagation::default()).unwrap();
        // c'(q) along the original solid, channel `ch`.
        let blended = |q: [f64; 3], ch: usize| {
            let mut c = [0f32; 3];
            before.eval(q.map(|v| v as f32), &mut c);
            let c: Vec<f64> = c.iter().map(|&v| v as f64).collect();
            let h = inf.h(q, &c);
            (1.0 - h) * c[ch] + h * reference[ch]
        };
        // Control points sit on cube faces, where the interpolant is C^1 but not C^2: central
        // differences converge at first order there, so extrapolate linearly from two steps.
        let diff = |p: [f64; 3], ch: usize, axis: usize, e: f64| {
            let (mut a, mut b) = (p, p);
            a[axis] += e;
            b[axis] -= e;
            (blended(a, ch) - blended(b, ch)) / (2.0 * e)
        };
        for point in [[1u32, 1, 1], [2, 1, 2], [1, 2, 1]] {
            let p = point.map(|v| (v * super::super::SPACING) as f64);
            for ch in 0..3 {
                let stored = s.at(point, ch as u32).to_vec();
                assert!((stored[0] as f64 - blended(p, ch)).abs() < 1e-3);
                for axis in 0..3 {
                    let g = 2.0 * diff(p, ch, axis, 0.025) - diff(p, ch, axis, 0.05);
                    let want = stored[1 + axis] as f64;
                    assert!(
                        (g - want).abs() < 1e-2 * (1.0 + want.abs()),
                        "{point:?} ch {ch} axis {axis}: {g} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn bad_strokes_are_refused() {
        for bad in [
            r#"{"strokes": []}"#,
            r#"{"strokes": [{"position": [0, 0], "strength": 1}]}"#,
            r#"{"strokes": [{"position": [0, 0, 0], "strength": 2}]}"#,
            r#"[1, 2]"#,
        ] {
            assert!(parse_strokes(bad, "s").is_err(), "{bad}");
        }
    }
}
