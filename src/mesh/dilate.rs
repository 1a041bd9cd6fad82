//! Dilation of a baked atlas: texels no triangle set take their baked neighbours' colours, ring
//! by ring, so bilinear filtering and mip levels near a cell's or UV island's border read the
//! surface's colours rather than the background (the bake margin of Blender's and Substance's
//! bakers).

/// Fill the texels of `pixels` (rows of `width` texels, `texel_bytes` bytes each) that `placed`
/// (a bit per texel) lacks: each ring takes, per byte, the rounded mean of its texels' already
/// filled 8-neighbours, and is then marked placed. `rings` rings (`None`: until no texel is
/// left that touches a filled one). Each ring reads only the rings before it, so the result
/// does not depend on any visiting order.
pub fn dilate(
    pixels: &mut [u8],
    width: u32,
    height: u32,
    texel_bytes: usize,
    placed: &mut [u64],
    rings: Option<u32>,
) {
    if rings == Some(0) {
        return; // (the default packed atlas: no gutter, and no scan of its texels)
    }
    let (w, h) = (width as usize, height as usize);
    let is_set = |bits: &[u64], i: usize| bits[i / 64] & (1 << (i % 64)) != 0;
    let set = |bits: &mut [u64], i: usize| bits[i / 64] |= 1 << (i % 64);
    let neighbours = move |i: usize| {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        (-1..=1i64)
            .flat_map(move |dy| (-1..=1i64).map(move |dx| (x + dx, y + dy)))
            .filter(move |&(nx, ny)| {
                (nx, ny) != (x, y) && nx >= 0 && ny >= 0 && nx < w as i64 && ny < h as i64
            })
            .map(move |(nx, ny)| ny as usize * w + nx as usize)
    };
    // The first ring: unset texels next to a set one.
    let mut queued = vec![0u64; placed.len()];
    let mut ring: Vec<usize> = Vec::new();
    for i in 0..w * h {
        if !is_set(placed, i) && neighbours(i).any(|n| is_set(placed, n)) {
            ring.push(i);
            set(&mut queued, i);
        }
    }
    let mut done = 0;
    while !ring.is_empty() && rings.is_none_or(|r| done < r) {
        let values: Vec<u8> = ring
            .iter()
            .flat_map(|&i| {
                let mut sum = [0u32; 4];
                let mut count = 0u32;
                for n in neighbours(i).filter(|&n| is_set(placed, n)) {
                    for (c, s) in sum.iter_mut().enumerate().take(texel_bytes) {
                        *s += pixels[n * texel_bytes + c] as u32;
                    }
                    count += 1;
                }
                (0..texel_bytes).map(move |c| ((sum[c] + count / 2) / count) as u8)
            })
            .collect();
        for (k, &i) in ring.iter().enumerate() {
            pixels[i * texel_bytes..(i + 1) * texel_bytes]
                .copy_from_slice(&values[k * texel_bytes..(k + 1) * texel_bytes]);
        }
        for &i in &ring {
            set(placed, i);
        }
        let mut next = Vec::new();
        for &i in &ring {
            for n in neighbours(i) {
                if !is_set(placed, n) && !is_set(&queued, n) {
                    set(&mut queued, n);
                    next.push(n);
                }
            }
        }
        next.sort_unstable();
        ring = next;
        done += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(width: usize, height: usize, set: &[usize]) -> Vec<u64> {
        let mut b = vec![0u64; (width * height).div_ceil(64)];
        for &i in set {
            b[i / 64] |= 1 << (i % 64);
        }
        b
    }

    #[test]
    fn rings_spread_the_neighbours_mean_and_stop_when_asked() {
        // A 5 x 5 image, one grey texel in the middle.
        let mut px = vec![0u8; 25];
        px[12] = 200;
        let mut placed = bits(5, 5, &[12]);
        dilate(&mut px, 5, 5, 1, &mut placed, Some(1));
        // The eight neighbours take it; the border ring is left alone.
        for i in [6, 7, 8, 11, 13, 16, 17, 18] {
            assert_eq!(px[i], 200, "texel {i}");
        }
        assert_eq!(px[0], 0);
        assert_eq!(placed[0].count_ones(), 9);
        dilate(&mut px, 5, 5, 1, &mut placed, None);
        assert!(px.iter().all(|&v| v == 200));
        assert_eq!(placed[0].count_ones(), 25);
    }

    #[test]
    fn a_texel_between_two_colours_takes_their_rounded_mean_per_byte() {
        // Row of three RGB texels: red, (empty), blue.
        let mut px = vec![255, 0, 0, 0, 0, 0, 0, 0, 255];
        let mut placed = bits(3, 1, &[0, 2]);
        dilate(&mut px, 3, 1, 3, &mut placed, None);
        assert_eq!(&px[3..6], &[128, 0, 128]);
    }

    #[test]
    fn nothing_set_leaves_everything_alone() {
        let mut px = vec![7u8; 12];
        let mut placed = bits(4, 3, &[]);
        dilate(&mut px, 4, 3, 1, &mut placed, None);
        assert!(px.iter().all(|&v| v == 7));
        assert_eq!(placed[0], 0);
    }
}
