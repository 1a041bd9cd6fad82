//! The causal neighbourhood of a block: which of its overlaps with already synthesized blocks
//! it has (its [`Shape`]), as disjoint rectangles.

/// A rectangle of pixels relative to a block's top-left corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

/// Which neighbours a block overlaps: the shape of its causal neighbourhood.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// A block of the first row (after the first): its left overlap.
    Left,
    /// A block of the first column: its top overlap.
    Top,
    /// Every other block: the L of top and left overlaps.
    Both,
}

/// The three rectangles neighbourhoods are made of: the top strip (overlap x block), the corner
/// (overlap x overlap) and the lower-left strip (below the corner).
const TOP: usize = 0;
const CORNER: usize = 1;
const LOWER_LEFT: usize = 2;

pub(super) fn parts(shape: Shape) -> &'static [usize] {
    match shape {
        Shape::Left => &[CORNER, LOWER_LEFT],
        Shape::Top => &[TOP],
        Shape::Both => &[TOP, LOWER_LEFT],
    }
}

pub(super) fn part_rect(part: usize, block: u32, overlap: u32) -> Rect {
    match part {
        TOP => Rect {
            x: 0,
            y: 0,
            w: block,
            h: overlap,
        },
        CORNER => Rect {
            x: 0,
            y: 0,
            w: overlap,
            h: overlap,
        },
        _ => Rect {
            x: 0,
            y: overlap,
            w: overlap,
            h: block - overlap,
        },
    }
}

/// The disjoint rectangles of a neighbourhood shape for blocks of side `block`, overlap `overlap`.
pub fn template(shape: Shape, block: u32, overlap: u32) -> Vec<Rect> {
    parts(shape)
        .iter()
        .map(|&p| part_rect(p, block, overlap))
        .collect()
}
