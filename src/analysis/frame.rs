//! The axis frame tying exemplars to the volume, and packed 2D coordinates.
//!
//! Exemplar E_a (a = 0, 1, 2 for x, y, z) lies in the plane orthogonal to volume axis a. Its image
//! column u runs along volume axis (a+1) mod 3 and its row v along (a+2) mod 3:
//!
//! | exemplar | u (column) | v (row) |
//! |----------|------------|---------|
//! | Ex       | y          | z       |
//! | Ey       | z          | x       |
//! | Ez       | x          | y       |
//!
//! Why this cyclic orientation (our reading of the paper's Fig. 3): it is the only one in which a
//! single image can serve all three axes with one shared candidate set, which the paper reports
//! doing (6.1). In it, the line along volume axis t is the *V strip* (column through the pixel)
//! of E_{t+1} and the *H strip* (row) of E_{t+2}, so the crossbar error of a triple (p0, p1, p2) is
//!
//!   CB = |V0(p0) - H1(p1)|^2 + |V1(p1) - H2(p2)|^2 + |V2(p2) - H0(p0)|^2,
//!
//! invariant under the cyclic rotation (p0, p1, p2) -> (p1, p2, p0). So when E0 = E1 = E2 the
//! candidates of E1 and E2 are rotations of those of E0 and are computed once.
//! Consequence for synthesis: coordinate inheritance reads
//! child_a = 2 parent_a + (offset along axis a+1, offset along axis a+2).
//!
//! The paper's own inheritance puts Ey the other way round,
//! columns along x and rows along z, so that Ex and Ey share "up". Inputs given in that frame
//! ([`InputFrame::Paper`], the command line's default) are brought into this one by transposing
//! Ey ([`to_crate_frame`]): the same geometry, with the machinery above unchanged.

/// How exemplar images lie in the three planes, as users give them (`--frame`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum InputFrame {
    /// The paper's coordinate inheritance: Ex columns along y, rows along z; Ey columns along
    /// x, rows along z; Ez columns along x, rows along y. The planes orthogonal to x and y share
    /// their rows' axis (z, "up"), so layered structures and directional lighting in one image
    /// agree in two of the three planes. One image becomes three exemplars (Ey transposed),
    /// about twice the analysis time. The default where it fits.
    Paper,
    /// Ex columns along y, rows along z; Ey columns along z, rows along x; Ez columns along x,
    /// rows along y: one image serves all three planes with one shared candidate set; no two
    /// planes agree on "up".
    Cyclic,
}

/// `paper` or `cyclic`, as `--frame` spells them.
impl std::str::FromStr for InputFrame {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        match text {
            "paper" => Ok(InputFrame::Paper),
            "cyclic" => Ok(InputFrame::Cyclic),
            _ => Err("expected paper or cyclic".into()),
        }
    }
}

/// Whether `images` (one for all planes, or Ex, Ey, Ez) can be given in the paper's frame: Ey
/// transposed must have Ex's size (every square image can; a non-square one only as three
/// exemplars with Ey given turned).
pub fn paper_frame_fits(images: &[crate::exemplar::Image]) -> bool {
    if images.is_empty() {
        return false;
    }
    let (x, y) = (&images[0], &images[images.len().min(2) - 1]);
    (y.height, y.width) == (x.width, x.height)
}

/// The frame of `images` when the user named none: the paper's where it fits
/// ([`paper_frame_fits`]), else the cyclic one.
pub fn default_frame(images: &[crate::exemplar::Image]) -> InputFrame {
    if paper_frame_fits(images) {
        InputFrame::Paper
    } else {
        InputFrame::Cyclic
    }
}

/// The frame `images` are taken in: `requested`, or by default [`default_frame`]. A requested
/// paper frame that does not fit ([`paper_frame_fits`]) is an input error.
pub fn resolve_frame(
    images: &[crate::exemplar::Image],
    requested: Option<InputFrame>,
) -> crate::Result<InputFrame> {
    if !matches!(images.len(), 1 | 3) {
        return Err(crate::Error::invalid(
            "exemplars",
            format!(
                "{} images: give one (all planes) or three (x, y, z)",
                images.len()
            ),
        ));
    }
    match requested {
        Some(InputFrame::Paper) if !paper_frame_fits(images) => {
            let y = &images[images.len().min(2) - 1];
            Err(crate::Error::invalid(
                "--frame paper",
                format!(
                    "transposes the y exemplar ({}x{}), which then no longer has the x \
                     exemplar's size; use a square image or --frame cyclic",
                    y.width, y.height
                ),
            ))
        }
        Some(frame) => Ok(frame),
        None => Ok(default_frame(images)),
    }
}

/// The exemplars (one for all planes, or Ex, Ey, Ez) in the crate's frame, given in `frame`:
/// with [`InputFrame::Paper`] three images, Ey transposed (the paper's Ey has columns along x
/// and rows along z, the crate's columns along z and rows along x). Masks go through the same.
pub fn to_crate_frame(
    mut images: Vec<crate::exemplar::Image>,
    frame: InputFrame,
) -> Vec<crate::exemplar::Image> {
    if frame == InputFrame::Paper {
        if images.len() == 1 {
            images = vec![images[0].clone(), images[0].clone(), images[0].clone()];
        }
        images[1] = images[1].transposed();
    }
    images
}

pub use crate::contract::pca::{HALF, NEIGHBOURHOOD, NEIGHBOURHOOD_PIXELS};
pub use crate::contract::triple::{next, pack, rotate_from_shared, unpack, NO_COORD};
