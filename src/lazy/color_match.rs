//! The colour table of `--color matched`: the voxels' mean colour given the exemplars' mean
//! colour and contrast.
//!
//! The paper colours a voxel with the mean of its three exemplar pixels. A mean of three is
//! drawn toward the middle: the solid's colours span a narrower range than the exemplar's and
//! its edges are weaker (stone_brick: standard deviation of red 40 in the solid against 54 in
//! the exemplar; slices' mean gradient 0.78 of the exemplar's). The table moves each colour
//! channel's mean to the exemplars' and scales the deviations from it by one gain for all
//! channels, the ratio of the total standard deviations: contrast comes back and hues keep
//! their direction. (Full per-channel histogram matching scored better on most photographs but
//! turned the built-in exemplar's blue cells purple and its tan cells olive: matching each
//! channel's marginal on its own moves colours off their hue.)
//!
//! The solid's statistics come from a probe: a tileable solid synthesized with the same
//! analysis and parameters when the session starts ([`probe_edge`]). Not from the requested
//! region, so the table is the same for every region and the output stays a pointwise
//! function of the solid (spatial determinism is untouched). The probe must hold enough of the
//! texture's structure: with full matching, a 32^3 probe of stone_brick (about one brick) left
//! its histogram ratio at 1.80 where a 96^3 one gave 0.73. (The 3D candidates' means, which
//! need no probe, are far wider than a solid's: a table from them barely stretched.)

/// Channels a table word holds (one byte each).
const WORD_CHANNELS: usize = 4;

/// Edge of the probe for a finest-level exemplar `width` wide: about one exemplar, so that the
/// probe holds as much structure as the exemplar does (a multiple of 32, as tileable solids in
/// one piece are, from 64 to 128).
pub fn probe_edge(width: u32) -> u32 {
    width.div_ceil(32).clamp(2, 4) * 32
}

/// The identity table: 256 words, byte c of word k equal to k.
pub fn identity() -> Vec<u32> {
    (0..256u32).map(|k| k * 0x0101_0101).collect()
}

/// Per colour channel (at most 4), the histogram of the bytes of `pixels`, `stride` bytes per
/// pixel.
pub fn histograms(pixels: &[u8], stride: usize, colors: usize) -> Vec<[u64; 256]> {
    let colors = colors.min(WORD_CHANNELS);
    let mut h = vec![[0u64; 256]; colors];
    for px in pixels.chunks_exact(stride) {
        for (ch, hist) in h.iter_mut().enumerate() {
            hist[px[ch] as usize] += 1;
        }
    }
    h
}

/// Mean and variance of a histogram.
fn moments(h: &[u64; 256]) -> (f64, f64) {
    let n = h.iter().sum::<u64>().max(1) as f64;
    let mean = h
        .iter()
        .enumerate()
        .map(|(v, &c)| v as f64 * c as f64)
        .sum::<f64>()
        / n;
    let var = h
        .iter()
        .enumerate()
        .map(|(v, &c)| (v as f64 - mean).powi(2) * c as f64)
        .sum::<f64>()
        / n;
    (mean, var)
}

/// The table taking `source`'s statistics to `target`'s (per colour channel, histograms of
/// the same channels): byte c of word k the output value of channel c for value k, each
/// channel's mean moved to the target's and deviations scaled by one gain for all channels
/// (the ratio of the total standard deviations), rounded and clamped to 0..=255. Channels
/// without histograms (the feature channel) map to themselves. Computed in f64 from integer
/// counts, in a fixed order: the same table on every machine.
pub fn table(source: &[[u64; 256]], target: &[[u64; 256]]) -> Vec<u32> {
    let (s, t): (Vec<_>, Vec<_>) = (
        source.iter().map(moments).collect(),
        target.iter().map(moments).collect(),
    );
    let (vs, vt): (f64, f64) = (s.iter().map(|m| m.1).sum(), t.iter().map(|m| m.1).sum());
    let gain = if vs > 0.0 { (vt / vs).sqrt() } else { 1.0 };
    let mut words = identity();
    for (ch, (s, t)) in s.iter().zip(&t).enumerate().take(WORD_CHANNELS) {
        for (k, w) in words.iter_mut().enumerate() {
            let v = (t.0 + gain * (k as f64 - s.0)).round().clamp(0.0, 255.0) as u32;
            *w = (*w & !(0xFF << (ch * 8))) | (v << (ch * 8));
        }
    }
    words
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_narrow_source_gets_the_target_contrast_and_mean() {
        // Two channels: source values 100..=110 (mean 105), target 40..=240 step 20 (mean
        // 140): twenty times the spread; channel 1 the same with its own means.
        let source: Vec<u8> = (0..11u8).flat_map(|i| [100 + i, 50 + i]).collect();
        let target: Vec<u8> = (0..11u8).flat_map(|i| [40 + 20 * i, 10 + 20 * i]).collect();
        let t = table(&histograms(&source, 2, 2), &histograms(&target, 2, 2));
        assert_eq!(t.len(), 256);
        let (c0, c1) = (|k: usize| t[k] & 0xFF, |k: usize| (t[k] >> 8) & 0xFF);
        assert_eq!(c0(105), 140);
        assert_eq!(c0(100), 40);
        assert_eq!(c0(110), 240);
        assert_eq!(c1(55), 110);
        assert_eq!(c1(50), 10);
        // Clamped, monotone.
        assert_eq!(c0(0), 0);
        assert_eq!(c0(255), 255);
        for k in 1..256 {
            assert!(c0(k) >= c0(k - 1) && c1(k) >= c1(k - 1), "{k}");
        }
        // Channels 2 and 3 (no histograms): themselves.
        assert_eq!(t[9] >> 16, 0x0909);
    }

    #[test]
    fn the_same_statistics_give_the_identity() {
        let pixels: Vec<u8> = (0..=255u8).flat_map(|v| [v, v / 2, 255 - v]).collect();
        let h = histograms(&pixels, 3, 3);
        assert_eq!(table(&h, &h), identity());
        assert_eq!(identity()[7], 0x0707_0707);
    }

    #[test]
    fn a_flat_source_is_moved_but_not_scaled() {
        let t = table(&histograms(&[90, 90], 1, 1), &histograms(&[10, 30], 1, 1));
        assert_eq!(t[90] & 0xFF, 20);
        assert_eq!(t[91] & 0xFF, 21);
    }

    #[test]
    fn probes_hold_about_one_exemplar() {
        assert_eq!(probe_edge(32), 64);
        assert_eq!(probe_edge(64), 64);
        assert_eq!(probe_edge(96), 96);
        assert_eq!(probe_edge(156), 128);
    }
}
