//! What the `tricubic_eval` kernel reads: a gradient solid's control grid (built and edited by
//! `gradient`), the Hermite bases in the kernels' order of operations, and the query points.

/// Control-point spacing in voxels (the paper's d).
pub const SPACING: u32 = 4;
#[derive(Clone, Debug, PartialEq)]
pub struct GradientSolid {
    /// Control points per axis.
    pub dims: [u32; 3],
    /// Feature channels (e.g. 3 for RGB, 0..255 scale).
    pub channels: u32,
    /// Per point (x fastest), per channel: f, df/dx, df/dy, df/dz (per voxel).
    pub data: Vec<f32>,
    /// Trailing channels that hold the detail residual's standard deviation sigma (paper 5.4),
    /// one per colour channel, or 0. See `gradient::detail`.
    pub detail: u32,
    /// The voxels (x, y, z) from voxel 0 the solid stands for: a vectorized volume's size, a
    /// synthesized solid's period (at most the extent, d (n - 1) + 1); what a render draws by
    /// default.
    pub size: [u32; 3],
    /// The solid repeats with period `size` (a synthesized solid, whose last face of control
    /// points repeats the first): a render wraps points into [0, size). Otherwise points
    /// outside the control grid take the value at its nearest boundary.
    pub periodic: bool,
}

impl GradientSolid {
    /// Refuse a solid built by hand whose fields disagree: at least 2 control points per axis,
    /// 1..=16 channels, 4 finite values (a value and its three derivatives) per channel and
    /// control point.
    pub fn check(&self) -> crate::Result<()> {
        let what = "gradient solid";
        if self.dims.iter().any(|&d| d < 2) || !(1..=16).contains(&self.channels) {
            return Err(crate::Error::invalid(
                what,
                format!(
                    "needs at least 2 control points per axis and 1..=16 channels, got {:?} x {}",
                    self.dims, self.channels
                ),
            ));
        }
        crate::Error::check_held(
            what,
            self.data.len(),
            &self.dims,
            u64::from(self.channels) * 4,
            "values",
            || {
                format!(
                    "{:?} control points of {} channels (4 values each) take",
                    self.dims, self.channels
                )
            },
        )?;
        if let Some(i) = self.data.iter().position(|v| !v.is_finite()) {
            return Err(crate::Error::invalid(what, format!("value {i} is not finite")));
        }
        let cells = self.dims.map(|n| SPACING * (n - 1));
        let fits = (0..3).all(|a| (1..=cells[a] + 1).contains(&self.size[a]));
        if !fits || (self.periodic && self.size != cells) {
            return Err(crate::Error::invalid(
                what,
                format!(
                    "stands for {:?} voxels{}; its control points span {cells:?} cells of {SPACING} \
                     voxels (a periodic solid's size is that span, another's at most one more)",
                    self.size,
                    if self.periodic { ", periodic" } else { "" }
                ),
            ));
        }
        Ok(())
    }
}

/// Cubic Hermite value basis of corner `c` (0 or 1) at `s` in [0, 1] (the kernels' order of
/// operations).
#[inline]
pub fn hermite_h(c: u32, s: f32) -> f32 {
    if c == 0 {
        2.0 * s * s * s - 3.0 * s * s + 1.0
    } else {
        3.0 * s * s - 2.0 * s * s * s
    }
}

/// Cubic Hermite derivative basis of corner `c` at `s`, scaled to per-voxel gradients.
#[inline]
pub fn hermite_g(c: u32, s: f32) -> f32 {
    let d = SPACING as f32;
    if c == 0 {
        d * (s * s * s - 2.0 * s * s + s)
    } else {
        d * (s * s * s - s * s)
    }
}

/// Where to evaluate.
#[derive(Clone, Debug, PartialEq)]
pub enum Query {
    /// origin + i a + j b + k c for i < n\[0\], j < n\[1\], k < n\[2\] (i fastest): a volume with unit
    /// axes, or a slice of any orientation with n\[2\] = 1.
    Grid {
        origin: [f32; 3],
        a: [f32; 3],
        b: [f32; 3],
        c: [f32; 3],
        n: [u32; 3],
    },
    /// Explicit voxel-space points.
    Points(Vec<[f32; 3]>),
}

impl Query {
    /// The box [0, n)^3 at integer voxel positions.
    pub fn volume(n: [u32; 3]) -> Query {
        Query::Grid {
            origin: [0.0; 3],
            a: [1.0, 0.0, 0.0],
            b: [0.0, 1.0, 0.0],
            c: [0.0, 0.0, 1.0],
            n,
        }
    }

    pub fn len(&self) -> usize {
        match self {
            Query::Grid { n, .. } => n.iter().map(|&v| v as usize).product(),
            Query::Points(p) => p.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Point `idx`, computed in the shader's order of operations.
    pub fn point(&self, idx: usize) -> [f32; 3] {
        match self {
            Query::Grid { origin, a, b, c, n } => {
                let i = (idx % n[0] as usize) as f32;
                let j = ((idx / n[0] as usize) % n[1] as usize) as f32;
                let k = (idx / (n[0] as usize * n[1] as usize)) as f32;
                [0, 1, 2].map(|d| origin[d] + i * a[d] + j * b[d] + k * c[d])
            }
            Query::Points(p) => p[idx],
        }
    }
}

/// The 8-bit value of an evaluated channel: rounded half up, clamped to [0, 255] (what the
/// kernel's `quantize` mode writes, and what renders store).
#[inline]
pub fn quantize(v: f32) -> u8 {
    (v + 0.5).floor().clamp(0.0, 255.0) as u8
}
