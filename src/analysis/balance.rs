//! Usage-balancing parameters stored with an analysis: how many calibration rounds and how large
//! a penalty may be. The measurement itself runs syntheses, so it lives in the synthesis layer
//! (`lazy::balance`), which explains the method.

/// Calibration rounds by default (4: measured; 2 leaves brick's histogram ratio at 4.1, 8 gains
/// little over 4).
pub const DEFAULT_ROUNDS: u32 = 4;
/// Most rounds accepted.
pub const MAX_ROUNDS: u32 = 16;
/// Largest penalty of one pixel, in sixteenths (a distance scaled by up to 16x per coordinate).
/// Three of them plus 16, times the largest distance (3 planes x 12 dims x 255^2), stays below
/// 2^32: the kernels' u32 products cannot overflow.
pub const MAX_PENALTY: u8 = 255;
