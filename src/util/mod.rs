//! Small shared helpers.

pub mod cancel;
// Only the command line checks free space before writing (its Zarr regions).
#[cfg(feature = "cli")]
pub mod disk;
pub mod gzip;
pub mod hash;
pub mod memory;

/// A number for a message: as written when of ordinary size, in scientific notation when very
/// large or small (`1e308` rather than its 309 digits).
pub fn number_text(v: f64) -> String {
    let magnitude = v.abs();
    if v == 0.0 || !v.is_finite() || (1e-4..1e15).contains(&magnitude) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn numbers_in_messages_stay_short() {
        assert_eq!(super::number_text(2.5), "2.5");
        assert_eq!(super::number_text(1e308), "1e308");
        assert_eq!(super::number_text(-3e-300), "-3e-300");
        assert_eq!(super::number_text(0.0), "0");
        assert_eq!(super::number_text(f64::INFINITY), "inf");
    }
}
