use super::*;
use crate::gradient::vectorize::{render, rms, vectorize};

/// A ball of one colour in another, with gentle shading in each region.
fn two_regions(n: u32) -> (Volume, Volume) {
    let mut v = Volume::new(n, n, n, 3);
    let mut m = Volume::new(n, n, n, 1);
    let c = (n as f64 - 1.0) / 2.0;
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let r = ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2))
                    .sqrt();
                let inside = r < n as f64 * 0.3;
                m.at_mut(x, y, z)[0] = if inside { 255 } else { 0 };
                let shade = (x + y) as f64 * 0.5;
                let px = v.at_mut(x, y, z);
                if inside {
                    px.copy_from_slice(&[(200.0 + shade * 0.3) as u8, 40, 30]);
                } else {
                    px.copy_from_slice(&[30, (60.0 + shade) as u8, 190]);
                }
            }
        }
    }
    (v, m)
}

#[test]
fn a_planar_boundary_is_almost_exact() {
    let n = 25u32;
    let mut v = Volume::new(n, n, n, 1);
    let mut m = Volume::new(n, n, n, 1);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let inside = x < 12;
                m.at_mut(x, y, z)[0] = if inside { 255 } else { 0 };
                v.at_mut(x, y, z)[0] = if inside { 220 - y as u8 } else { 20 + z as u8 };
            }
        }
    }
    let e_plain = rms(&render(&vectorize(&v).unwrap(), [n; 3]), &v);
    let rs = vectorize_regions(&v, &m, "mask").unwrap();
    let e = rms(&rs.render([n; 3], &Compute::Cpu, Blend::Exact).unwrap(), &v);
    assert!(e < 0.5 && e_plain > 20.0, "regions {e} vs plain {e_plain}");
}

#[test]
fn distance_transform_matches_brute_force() {
    let n = 11u32;
    let mut m = Volume::new(n, 7, 5, 1);
    let mut rng = crate::util::hash::SeededRng::new(3);
    for b in m.data.iter_mut() {
        *b = if rng.below(5) == 0 { 255 } else { 0 };
    }
    let sd = signed_distance(&m);
    let set: Vec<[i64; 3]> = (0..m.data.len())
        .filter(|&i| m.data[i] >= 128)
        .map(|i| [(i % 11) as i64, ((i / 11) % 7) as i64, (i / 77) as i64])
        .collect();
    for i in 0..m.data.len() {
        let p = [(i % 11) as i64, ((i / 11) % 7) as i64, (i / 77) as i64];
        if m.data[i] >= 128 {
            assert!(sd[i] >= 0.0);
            continue;
        }
        let best = set
            .iter()
            .map(|q| {
                (((p[0] - q[0]).pow(2) + (p[1] - q[1]).pow(2) + (p[2] - q[2]).pow(2)) as f64).sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        assert!((sd[i] as f64 - (0.5 - best)).abs() < 1e-5, "voxel {i}");
    }
}

#[test]
fn regions_keep_the_boundary_sharp_and_round_trip() {
    let (v, m) = two_regions(33);
    let plain = vectorize(&v).unwrap();
    let e_plain = rms(&render(&plain, [33, 33, 33]), &v);
    let rs = vectorize_regions(&v, &m, "mask").unwrap();
    assert!(rs.split_points() > 0);
    let exact = rs.render([33; 3], &Compute::Cpu, Blend::Exact).unwrap();
    let e_regions = rms(&exact, &v);
    // The boundary of a voxelized ball is itself jagged at the 4-voxel control spacing: a
    // few hundred boundary voxels still take the other side's colour.
    assert!(
        e_regions < 0.6 * e_plain,
        "regions {e_regions} vs plain {e_plain}"
    );
    let mut refined = rs.clone();
    let history = refined.optimize(&v, 20);
    assert!(history.windows(2).all(|w| w[1] <= w[0] + 1e-9));
    let e_opt = rms(
        &refined
            .render([33; 3], &Compute::Cpu, Blend::Exact)
            .unwrap(),
        &v,
    );
    assert!(e_opt < e_regions, "optimized {e_opt} vs {e_regions}");
    let aa = rs
        .render([33; 3], &Compute::Cpu, Blend::Antialiased)
        .unwrap();
    assert!(rms(&aa, &v) < e_plain);
    // Round trips: f32 exactly, 8-bit within quantization.
    let back = RegionSolid::from_bytes(&rs.to_bytes(Encoding::F32), "t").unwrap();
    assert_eq!(back, rs);
    let q = RegionSolid::from_bytes(&rs.to_bytes(Encoding::U8), "t").unwrap();
    assert_eq!(q.split, rs.split);
    let e_q = rms(&q.render([33; 3], &Compute::Cpu, Blend::Exact).unwrap(), &v);
    assert!(e_q < e_regions + 3.0, "8-bit {e_q} vs {e_regions}");
    // Corrupt files are refused, never a panic.
    let good = rs.to_bytes(Encoding::U8);
    let mut rng = crate::util::hash::SeededRng::new(9);
    for _ in 0..500 {
        let mut b = good.clone();
        let i = rng.below(b.len() as u64) as usize;
        b[i] ^= 1 << rng.below(8);
        if rng.below(2) == 0 {
            b.truncate(rng.below(b.len() as u64) as usize);
        }
        if b != good {
            assert!(RegionSolid::from_bytes(&b, "t").is_err());
        }
    }
    // A mask of the wrong size or with one region is refused.
    let small = Volume::new(8, 8, 8, 1);
    assert!(vectorize_regions(&v, &small, "m.nrrd")
        .unwrap_err()
        .to_string()
        .contains("must match"));
    let empty = Volume::new(33, 33, 33, 1);
    assert!(vectorize_regions(&v, &empty, "m.nrrd")
        .unwrap_err()
        .to_string()
        .contains("single region"));
}

/// Mutations with the trailing checksum recomputed: the nested grids, split flags and
/// negative set are checked; the parser returns an error or a consistent solid, never
/// panics.
#[test]
fn fuzz_structure_behind_a_valid_checksum() {
    let (v, m) = two_regions(13);
    let rs = vectorize_regions(&v, &m, "mask").unwrap();
    let mut rng = crate::util::hash::SeededRng::new(8);
    let (mut accepted, mut refused) = (0, 0);
    for round in 0..1500 {
        let encoding = if round % 2 == 0 {
            Encoding::U8
        } else {
            Encoding::F32
        };
        let good = rs.to_bytes(encoding);
        let mut b = good[..good.len() - 4].to_vec();
        for _ in 0..1 + rng.below(3) {
            let i = if rng.below(2) == 0 {
                rng.below(80.min(b.len() as u64)) as usize
            } else {
                rng.below(b.len() as u64) as usize
            };
            b[i] = match rng.below(3) {
                0 => b[i] ^ (1 << rng.below(8)),
                1 => rng.below(256) as u8,
                _ => [0, 1, 2, 255][rng.below(4) as usize],
            };
        }
        if rng.below(5) == 0 {
            b.truncate(rng.below(b.len() as u64) as usize);
        }
        let crc = crc32fast::hash(&b);
        b.extend(crc.to_le_bytes());
        match RegionSolid::from_bytes(&b, "t") {
            Ok(r) => {
                accepted += 1;
                let points: usize = r.positive.dims.iter().map(|&d| d as usize).product();
                assert_eq!(r.split.len(), points);
                assert_eq!(r.negative.data.len(), r.positive.data.len());
            }
            Err(_) => refused += 1,
        }
    }
    assert!(refused > 100, "{accepted} accepted, {refused} refused");
}
