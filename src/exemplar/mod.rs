//! Exemplar images: loading, the working 8-bit pixel grid, Gaussian pyramids and the optional
//! feature-distance channel.

pub mod feature;
pub mod procedural;
pub mod pyramid;

use crate::error::{Error, Result};
use std::path::Path;

/// Smallest exemplar side accepted: the 5x5 neighbourhoods of four pyramid levels need it.
pub const MIN_EXEMPLAR_SIDE: u32 = 16;
/// Largest exemplar side accepted (analysis memory grows with the pixel count).
pub const MAX_EXEMPLAR_SIDE: u32 = 2048;

/// How neighbourhoods read pixels outside the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Border {
    /// The exemplar tiles: coordinates wrap around.
    Wrap,
    /// The exemplar does not tile: reads are mirrored at the edge (reflect-101), so no
    /// neighbourhood ever straddles the opposite edges (which would be a seam).
    Mirror,
}

impl Border {
    /// Map an integer coordinate into `0..len`.
    pub fn resolve(self, c: i32, len: u32) -> u32 {
        let n = len as i32;
        match self {
            Border::Wrap => c.rem_euclid(n) as u32,
            Border::Mirror => {
                if n == 1 {
                    return 0;
                }
                let period = 2 * (n - 1);
                let m = c.rem_euclid(period);
                (if m >= n { period - m } else { m }) as u32
            }
        }
    }
    pub fn code(self) -> u32 {
        match self {
            Border::Wrap => 0,
            Border::Mirror => 1,
        }
    }
    pub fn from_code(c: u32) -> Option<Self> {
        match c {
            0 => Some(Border::Wrap),
            1 => Some(Border::Mirror),
            _ => None,
        }
    }
}

/// An 8-bit image with interleaved channels, row-major, x fastest.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub pixels: Vec<u8>,
}

impl Image {
    pub fn new(width: u32, height: u32, channels: u32) -> Self {
        Image {
            width,
            height,
            channels,
            pixels: vec![0; width as usize * height as usize * channels as usize],
        }
    }
    /// Check a hand-built image: 1 to 4 channels, and pixels that match its sizes; `what` names
    /// it in errors.
    pub fn check(&self, what: &str) -> Result<()> {
        if !(1..=4).contains(&self.channels) {
            return Err(Error::invalid(
                what,
                format!("image has {} channels; 1 to 4 expected", self.channels),
            ));
        }
        Error::check_held(
            what,
            self.pixels.len(),
            &[self.width, self.height],
            u64::from(self.channels),
            "bytes",
            || {
                format!(
                    "{}x{} pixels of {} channels take",
                    self.width, self.height, self.channels
                )
            },
        )
    }
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
    /// The channels of pixel (x, y).
    pub fn at(&self, x: u32, y: u32) -> &[u8] {
        let i = ((y * self.width + x) * self.channels) as usize;
        &self.pixels[i..i + self.channels as usize]
    }
    /// The `width` x `height` pixels whose top-left corner is (x, y) (which must fit).
    pub fn crop(&self, x: u32, y: u32, width: u32, height: u32) -> Image {
        assert!(
            x + width <= self.width && y + height <= self.height,
            "crop inside the image"
        );
        let row = (width * self.channels) as usize;
        let mut out = Image::new(width, height, self.channels);
        for (r, dst) in out.pixels.chunks_exact_mut(row).enumerate() {
            let start = ((y + r as u32) * self.width + x) as usize * self.channels as usize;
            dst.copy_from_slice(&self.pixels[start..start + row]);
        }
        out
    }
    /// The image mirrored about its main diagonal: pixel (x, y) of the result is pixel (y, x)
    /// of this one.
    pub fn transposed(&self) -> Image {
        let c = self.channels as usize;
        let mut out = Image::new(self.height, self.width, self.channels);
        for y in 0..self.width {
            for x in 0..self.height {
                let dst = (y * self.height + x) as usize * c;
                out.pixels[dst..dst + c].copy_from_slice(self.at(y, x));
            }
        }
        out
    }
    /// The channels of pixel (x, y) after resolving out-of-range coordinates with `border`.
    pub fn at_border(&self, x: i32, y: i32, border: Border) -> &[u8] {
        self.at(
            border.resolve(x, self.width),
            border.resolve(y, self.height),
        )
    }
    /// A copy with the channels `range` only.
    pub fn select_channels(&self, range: std::ops::Range<u32>) -> Image {
        let c = range.len() as u32;
        let mut out = Image::new(self.width, self.height, c);
        for (dst, src) in out
            .pixels
            .chunks_exact_mut(c as usize)
            .zip(self.pixels.chunks_exact(self.channels as usize))
        {
            dst.copy_from_slice(&src[range.start as usize..range.end as usize]);
        }
        out
    }
    /// The same pixels with `target` channels, 1 to 4 channels being gray, gray and alpha, RGB
    /// and RGBA: gray replicated into RGB, alpha kept where both have it, an opaque alpha added,
    /// surplus colour channels dropped (RGB to gray keeps red).
    ///
    /// # Panics
    /// If either channel count is outside 1 to 4.
    pub fn with_channels(&self, target: u32) -> Image {
        assert!(
            (1..=4).contains(&self.channels) && (1..=4).contains(&target),
            "with_channels converts between 1 and 4 channels, not {} to {target}",
            self.channels
        );
        if self.channels == target {
            return self.clone();
        }
        let mut out = Image::new(self.width, self.height, target);
        for (d, s) in out
            .pixels
            .chunks_exact_mut(target as usize)
            .zip(self.pixels.chunks_exact(self.channels as usize))
        {
            let gray = s.len() <= 2;
            let alpha = match s.len() {
                2 | 4 => s[s.len() - 1],
                _ => 255,
            };
            for (k, v) in d.iter_mut().enumerate() {
                *v = match (target, k) {
                    (2, 1) | (4, 3) => alpha,
                    _ if gray => s[0],
                    (_, k) => s[k],
                };
            }
        }
        out
    }

    /// Append the channels of `other` (same size) after ours.
    pub fn with_extra_channels(&self, other: &Image) -> Image {
        assert_eq!((self.width, self.height), (other.width, other.height));
        let c = self.channels + other.channels;
        let mut out = Image::new(self.width, self.height, c);
        for ((dst, a), b) in out
            .pixels
            .chunks_exact_mut(c as usize)
            .zip(self.pixels.chunks_exact(self.channels as usize))
            .zip(other.pixels.chunks_exact(other.channels as usize))
        {
            dst[..a.len()].copy_from_slice(a);
            dst[a.len()..].copy_from_slice(b);
        }
        out
    }
    /// As an `image` buffer keeping the channel count (gray, RGB or RGBA), for saving.
    pub fn to_dynamic(&self) -> image::DynamicImage {
        let (w, h, px) = (self.width, self.height, self.pixels.clone());
        match self.channels {
            1 => image::DynamicImage::ImageLuma8(image::GrayImage::from_raw(w, h, px).unwrap()),
            3 => image::DynamicImage::ImageRgb8(image::RgbImage::from_raw(w, h, px).unwrap()),
            4 => image::DynamicImage::ImageRgba8(image::RgbaImage::from_raw(w, h, px).unwrap()),
            _ => image::DynamicImage::ImageRgba8(self.to_rgba8()),
        }
    }

    /// Convert to an RGB(A) `image` buffer for saving; gray is replicated.
    pub fn to_rgba8(&self) -> image::RgbaImage {
        image::RgbaImage::from_fn(self.width, self.height, |x, y| {
            let p = self.at(x, y);
            match p.len() {
                1 | 2 => image::Rgba([p[0], p[0], p[0], 255]),
                3 => image::Rgba([p[0], p[1], p[2], 255]),
                _ => image::Rgba([p[0], p[1], p[2], p[3]]),
            }
        })
    }
}

/// Decode an image file to 8 bits per channel, keeping 1 (gray), 3 (RGB) or 4 (RGBA) channels.
/// 16-bit and float inputs are rounded to 8 bits (the synthesis works on 8-bit colours).
/// `what` names the input in errors (a flag or "exemplar").
pub fn load_image(path: &Path, what: &str) -> Result<Image> {
    let bytes = crate::io::input::read(path)?;
    decode_image(&bytes, &format!("{what} {}", path.display()))
}

/// Decode image bytes (see [`load_image`]). An image whose header declares a side past
/// [`MAX_EXEMPLAR_SIDE`] is refused before it is decoded.
pub fn decode_image(bytes: &[u8], what: &str) -> Result<Image> {
    if let Some((w, h)) = image_dimensions(bytes) {
        if w > MAX_EXEMPLAR_SIDE || h > MAX_EXEMPLAR_SIDE {
            return Err(Error::invalid(
                what,
                format!(
                    "image is {w}x{h}; exemplars are at most {MAX_EXEMPLAR_SIDE} pixels a side"
                ),
            ));
        }
    }
    let decoded = image::load_from_memory(bytes)
        .map_err(|e| Error::invalid(what, format!("cannot decode image: {e}")))?;
    let (w, h) = (decoded.width(), decoded.height());
    if w == 0 || h == 0 {
        return Err(Error::invalid(what, format!("image is {w}x{h}")));
    }
    let color = decoded.color();
    let (channels, pixels) = match (color.has_color(), color.has_alpha()) {
        (false, false) => (1, decoded.into_luma8().into_raw()),
        (false, true) => {
            // Gray+alpha: keep as RGBA so alpha survives, with the gray replicated.
            (4, decoded.into_rgba8().into_raw())
        }
        (true, false) => (3, decoded.into_rgb8().into_raw()),
        (true, true) => (4, decoded.into_rgba8().into_raw()),
    };
    Ok(Image {
        width: w,
        height: h,
        channels,
        pixels,
    })
}

/// The width and height an image's header declares, if it can be read.
fn image_dimensions(bytes: &[u8]) -> Option<(u32, u32)> {
    image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .ok()?
        .into_dimensions()
        .ok()
}

/// Check an exemplar's size against the accepted range, and that an image built by hand holds
/// what its fields say: 1 (gray), 3 (RGB) or 4 (RGBA) channels, `width x height x channels`
/// bytes.
pub fn check_exemplar_size(img: &Image, what: &str) -> Result<()> {
    let (w, h) = (img.width, img.height);
    if ![1, 3, 4].contains(&img.channels) {
        return Err(Error::invalid(
            what,
            format!(
                "image has {} channels; exemplars have 1, 3 or 4",
                img.channels
            ),
        ));
    }
    if w < MIN_EXEMPLAR_SIDE || h < MIN_EXEMPLAR_SIDE {
        return Err(Error::invalid(
            what,
            format!("exemplar is {w}x{h}; each side must be at least {MIN_EXEMPLAR_SIDE} pixels"),
        ));
    }
    if w > MAX_EXEMPLAR_SIDE || h > MAX_EXEMPLAR_SIDE {
        return Err(Error::invalid(
            what,
            format!("exemplar is {w}x{h}; each side must be at most {MAX_EXEMPLAR_SIDE} pixels"),
        ));
    }
    img.check(what)
}

/// The exemplar built into the binary: a 128x128 slice of [`procedural::cells_3d`] (made by
/// `examples/generate_fixtures.rs`), saved as PNG.
pub const DEFAULT_EXEMPLAR_PNG: &[u8] = include_bytes!("../../assets/default-exemplar.png");

/// Decode the built-in default exemplar.
pub fn default_exemplar() -> Image {
    decode_image(DEFAULT_EXEMPLAR_PNG, "built-in exemplar").expect("built-in exemplar decodes")
}

#[cfg(test)]
mod tests {
    use super::Image;

    #[test]
    fn transposing_mirrors_about_the_diagonal() {
        // 3 x 2, two channels: pixel (x, y) holds (x, 10 y).
        let mut img = Image::new(3, 2, 2);
        for y in 0..2 {
            for x in 0..3 {
                let i = ((y * 3 + x) * 2) as usize;
                img.pixels[i..i + 2].copy_from_slice(&[x as u8, 10 * y as u8]);
            }
        }
        let t = img.transposed();
        assert_eq!((t.width, t.height, t.channels), (2, 3, 2));
        for y in 0..3 {
            for x in 0..2 {
                assert_eq!(t.at(x, y), img.at(y, x));
            }
        }
        assert_eq!(t.transposed().pixels, img.pixels);
    }
}
