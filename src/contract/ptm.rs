//! What the `ptm_relight` kernel reads: a polynomial texture map as quantized coefficients
//! (built, fitted and synthesized by `ptm`) and the light it is rendered under.

/// How a PTM stores colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum PtmFormat {
    /// One biquadratic polynomial per colour channel (18 coefficients a pixel).
    Rgb,
    /// One polynomial for the luminance and a constant colour per pixel (6 + 3 values): the pixel's
    /// colour under light l is L(l) * rgb.
    Lrgb,
}

impl PtmFormat {
    /// Bytes per texel in [`Ptm::texels`].
    pub fn texel_bytes(self) -> usize {
        match self {
            PtmFormat::Rgb => 18,
            PtmFormat::Lrgb => 9,
        }
    }

    /// Polynomials per texel (3 for RGB, 1 for LRGB).
    pub fn planes(self) -> usize {
        match self {
            PtmFormat::Rgb => 3,
            PtmFormat::Lrgb => 1,
        }
    }

    /// The format's name in a `.ptm` header.
    pub fn header_name(self) -> &'static str {
        match self {
            PtmFormat::Rgb => "PTM_FORMAT_RGB",
            PtmFormat::Lrgb => "PTM_FORMAT_LRGB",
        }
    }
}

/// Coefficients per polynomial: a0 lu^2 + a1 lv^2 + a2 lu lv + a3 lu + a4 lv + a5.
pub const COEFFS: usize = 6;

/// A polynomial texture map as the `.ptm` file holds it: quantized coefficients with one
/// (scale, bias) per coefficient index, shared by all pixels and planes.
///
/// The value of coefficient i stored as byte q is `(q - bias[i]) * scale[i]`, in the file's
/// units where 255 is full intensity (so a polynomial evaluating to 255 is white).
///
/// `texels` holds, per pixel (rows top to bottom, x fastest; the file stores rows bottom to top):
/// LRGB: a0..a5 of the luminance then r, g, b; RGB: a0..a5 of red, of green, of blue. Keeping the
/// bytes (not decoded floats) makes file round trips byte-identical and lets synthesis copy texels
/// exactly.
#[derive(Clone, Debug, PartialEq)]
pub struct Ptm {
    pub format: PtmFormat,
    pub width: u32,
    pub height: u32,
    pub scale: [f32; COEFFS],
    pub bias: [i32; COEFFS],
    pub texels: Vec<u8>,
}

impl Ptm {
    /// Refuse a PTM built by hand whose fields disagree: sides of at least one texel, its
    /// format's bytes for every texel, finite scales. `what` names it.
    pub fn check(&self, what: &str) -> crate::Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(crate::Error::invalid(
                what,
                format!("is {}x{} texels: it has none", self.width, self.height),
            ));
        }
        crate::Error::check_held(
            what,
            self.texels.len(),
            &[self.width, self.height],
            self.format.texel_bytes() as u64,
            "bytes of texels",
            || format!("a {}x{} PTM of its format takes", self.width, self.height),
        )?;
        if !self.scale.iter().all(|s| s.is_finite()) {
            return Err(crate::Error::invalid(what, "its scales must be finite"));
        }
        Ok(())
    }
}

/// Where the light is and how strong the highlight is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    pub lu: f32,
    pub lv: f32,
    /// Highlight strength (0: none).
    pub specular: f32,
}

impl Lighting {
    /// The z component of the unit light direction (0 for lights on or beyond the horizon).
    pub fn lw(&self) -> f32 {
        (1.0 - self.lu * self.lu - self.lv * self.lv)
            .max(0.0)
            .sqrt()
    }
}
