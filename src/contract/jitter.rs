//! The jitter field (paper 5.1): a continuous random warp made of Gaussians, defined everywhere in
//! Z^3 so that it does not depend on which box is synthesized. One Gaussian per 4^3 cell of the
//! l_start lattice, placed, sized and oriented by a hash of (seed, cell), with larger amplitude at
//! smaller width, as in the paper. The paper's numbers (about 200 Gaussians per unit volume, sigma
//! 0.01-0.05, amplitude 0.1-0.3) are not these: taking an exemplar-sized cube as the unit, a 128^2
//! exemplar's l_start cube is 16^3 voxels, which holds 64 Gaussians here, of sigma 1-2.5 voxels
//! (0.06-0.16) and amplitude 0.8-2 voxels (0.05-0.125) times --jitter. The paper's narrowest
//! Gaussians would be a fraction of an l_start voxel, a perturbation the correction undoes (the
//! paper: small-scale distortions are corrected by synthesis); --jitter scales the warp.
//! All in fixed point, so GPU and CPU agree. Tileable solids' l_start periods are whole cells
//! (`lazy::check_tileable_size`), so their cells repeat with the period and one lattice serves
//! every solid.

use crate::util::hash::hash32;

/// Cell side, in l_start voxels.
pub const CELL: i32 = 4;
/// Cells visited on each side of the voxel's cell (covers 3 sigma of the widest Gaussian).
pub const REACH: i32 = 2;
/// Gaussian widths (l_start voxels) and base amplitudes (voxels, scaled by --jitter).
pub const SIGMAS: [f64; 4] = [1.0, 1.5, 2.0, 2.5];
pub const AMPLITUDES: [f64; 4] = [2.0, 1.6, 1.2, 0.8];
/// Entries of the weight table: q = r^2 / sigma^2 in 1/16 units, up to 9 (3 sigma).
pub const WEIGHT_ENTRIES: usize = 144;
/// Unit directions in the table.
pub const DIRECTIONS: usize = 64;
/// Largest accepted --jitter (keeps the fixed-point sums inside i32).
pub const MAX_JITTER: f32 = 8.0;

/// The table the kernels read: exp(-q/32) * 65535 for q in 0..144, then 64 unit directions
/// (Fibonacci sphere) in 1/256 units, xyz.
pub fn table() -> Vec<u32> {
    let mut t: Vec<u32> = (0..WEIGHT_ENTRIES)
        .map(|q| ((-(q as f64) / 32.0).exp() * 65535.0).round() as u32)
        .collect();
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..DIRECTIONS {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / DIRECTIONS as f64;
        let r = (1.0 - z * z).sqrt();
        let phi = golden * i as f64;
        for c in [r * phi.cos(), r * phi.sin(), z] {
            t.push(((c * 256.0).round() as i32) as u32);
        }
    }
    t
}

/// Fixed-point amplitudes (1/256 voxel) for a user jitter magnitude.
pub fn amplitudes(jitter: f32) -> [i32; 4] {
    AMPLITUDES.map(|a| (a * jitter as f64 * 256.0).round() as i32)
}

/// sigma^2 in the units of q's denominator: r^2 is in 1/65536 voxel^2 and q in 1/16, so
/// q = r2 / (sigma^2 * 4096).
pub fn sigma2_fixed() -> [i32; 4] {
    SIGMAS.map(|s| (s * s * 4096.0).round() as i32)
}

/// Hash of a cell of the lattice for a seed (shared with the WGSL kernel `init`).
/// `period`: tileable solids' period in voxels (0: none; else whole cells); cells then repeat
/// with it.
pub fn cell_hash(seed_lo: u32, seed_hi: u32, c: [i32; 3], period: u32) -> u32 {
    debug_assert!(period.is_multiple_of(CELL as u32), "period {period}");
    let c = match period {
        0 => c,
        n => c.map(|v| v.rem_euclid(n as i32 / CELL)),
    };
    let mut h = hash32(seed_lo ^ 0x9E37_79B9);
    h = hash32(h ^ seed_hi);
    for v in c {
        h = hash32(h ^ v as u32);
    }
    h
}

/// Cell `c`'s low corner in 1/256 voxel. Positions far from the origin (cells beyond 2^21)
/// leave i32: they wrap, here as in the shaders' i32 arithmetic, and only their differences
/// (a voxel's offset from a nearby Gaussian, a few cells) are used, which the wrapping keeps
/// exact.
fn fixed(c: i32) -> i32 {
    c.wrapping_mul(CELL * 256)
}

/// One Gaussian of the field: centre (1/256 voxel), width class and direction index.
#[derive(Clone, Copy, Debug, Default)]
pub struct Gaussian {
    centre: [i32; 3],
    shape: usize,
    dir: usize,
}

/// All Gaussians a voxel of cell `cell` visits, in the kernel's order (cz, cy, cx ascending).
fn gaussians_around(cell: [i32; 3], seed_lo: u32, seed_hi: u32, period: u32) -> Vec<Gaussian> {
    let mut out = Vec::with_capacity(((2 * REACH + 1) as usize).pow(3));
    for cz in cell[2] - REACH..=cell[2] + REACH {
        for cy in cell[1] - REACH..=cell[1] + REACH {
            for cx in cell[0] - REACH..=cell[0] + REACH {
                let h = cell_hash(seed_lo, seed_hi, [cx, cy, cz], period);
                let shape = hash32(h ^ 4);
                out.push(Gaussian {
                    centre: [
                        fixed(cx).wrapping_add((hash32(h ^ 1) & 1023) as i32),
                        fixed(cy).wrapping_add((hash32(h ^ 2) & 1023) as i32),
                        fixed(cz).wrapping_add((hash32(h ^ 3) & 1023) as i32),
                    ],
                    shape: (shape & 3) as usize,
                    dir: ((shape >> 2) & 63) as usize,
                });
            }
        }
    }
    out
}

/// The Gaussians that reach some voxel of cell `cell` (in the kernel's order, which does not
/// matter to the integer sums). Every voxel of a cell shares them, so the CPU backend computes
/// them once per cell. Those left out lie beyond the weight table's 3 sigma (`sig2` as
/// [`sigma2_fixed`]) from every voxel of the cell and add exactly zero to its integer sum.
pub fn cell_gaussians(
    cell: [i32; 3],
    seed_lo: u32,
    seed_hi: u32,
    period: u32,
    sig2: [i32; 4],
) -> Vec<Gaussian> {
    // The cell's voxel centres span [lo, hi] per axis, in 1/256 voxel.
    let lo = cell.map(|c| fixed(c).wrapping_add(128));
    let hi = lo.map(|v| v.wrapping_add((CELL - 1) * 256));
    let mut out = gaussians_around(cell, seed_lo, seed_hi, period);
    out.retain(|g| {
        // Squared distance from the centre to the nearest voxel centre of the cell: a lower
        // bound of every voxel's r2 in `offset_from`.
        let nearest: i32 = (0..3)
            .map(|i| {
                (lo[i].wrapping_sub(g.centre[i]))
                    .max(g.centre[i].wrapping_sub(hi[i]))
                    .max(0)
            })
            .map(|d| d * d)
            .sum();
        nearest < WEIGHT_ENTRIES as i32 * sig2[g.shape]
    });
    out
}

/// The cell of l_start voxel `p`.
pub fn cell_of(p: [i32; 3]) -> [i32; 3] {
    p.map(|v| v.div_euclid(CELL))
}

/// The warp offset (whole voxels) at l_start voxel `p` (CPU side of `wgsl/init.wgsl`).
#[cfg(any(test, feature = "internals"))]
pub fn offset(
    p: [i32; 3],
    seed_lo: u32,
    seed_hi: u32,
    amps: [i32; 4],
    sig2: [i32; 4],
    table: &[u32],
) -> [i32; 3] {
    let gaussians = cell_gaussians(cell_of(p), seed_lo, seed_hi, 0, sig2);
    offset_from(p, &gaussians, amps, sig2, table)
}

/// The warp offset at `p` from its cell's Gaussians ([`cell_gaussians`] of [`cell_of`] p).
#[cfg(any(test, feature = "internals"))]
pub fn offset_from(
    p: [i32; 3],
    gaussians: &[Gaussian],
    amps: [i32; 4],
    sig2: [i32; 4],
    table: &[u32],
) -> [i32; 3] {
    let pos = p.map(|v| v.wrapping_mul(256).wrapping_add(128));
    let mut disp = [0i32; 3];
    for g in gaussians {
        let d = [0, 1, 2].map(|i| pos[i].wrapping_sub(g.centre[i]));
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        // Most of the 125 Gaussians lie beyond the table (3 sigma): rejected by a multiply
        // before the division (for r2, sig2 >= 0, r2 / sig2 < E exactly when r2 < E * sig2),
        // which cost more than the rest of the sum.
        let sig2 = sig2[g.shape];
        if r2 < WEIGHT_ENTRIES as i32 * sig2 {
            let q = r2 / sig2;
            let t = (amps[g.shape] * table[q as usize] as i32) >> 16;
            for i in 0..3 {
                disp[i] += t * table[WEIGHT_ENTRIES + g.dir * 3 + i] as i32;
            }
        }
    }
    disp.map(|v| (v + 32768) >> 16)
}

/// The warp offsets of the 64 voxels of cell `cell` (x fastest), from its Gaussians
/// ([`cell_gaussians`]): [`offset_from`] of each voxel, computed Gaussian by Gaussian. Each
/// Gaussian's squared distances are sums of per-axis squares (4 per axis), the voxels outside
/// its support are skipped by row, and q is divided in f64: exact, since q < 144 there and the
/// quotient of integers is at least 1 / sig2 from the next integer, far more than the rounding.
pub fn cell_offsets(
    cell: [i32; 3],
    gaussians: &[Gaussian],
    amps: [i32; 4],
    sig2: [i32; 4],
    table: &[u32],
) -> [[i32; 3]; 64] {
    let origin = cell.map(|c| fixed(c).wrapping_add(128));
    let mut disp = [[0i32; 3]; 64];
    for g in gaussians {
        let limit = WEIGHT_ENTRIES as i32 * sig2[g.shape];
        // Squared distance along each axis of the cell's 4 voxel centres.
        let sq: [[i32; 4]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|i| {
                let d = origin[a]
                    .wrapping_add(256 * i as i32)
                    .wrapping_sub(g.centre[a]);
                d * d
            })
        });
        let amp = amps[g.shape];
        let dir = WEIGHT_ENTRIES + g.dir * 3;
        let dir = [
            table[dir] as i32,
            table[dir + 1] as i32,
            table[dir + 2] as i32,
        ];
        for z in 0..4 {
            if sq[2][z] >= limit {
                continue;
            }
            for y in 0..4 {
                let yz = sq[2][z] + sq[1][y];
                if yz >= limit {
                    continue;
                }
                for x in 0..4 {
                    let r2 = yz + sq[0][x];
                    if r2 < limit {
                        let q = (r2 as f64 / sig2[g.shape] as f64) as usize;
                        let t = (amp * table[q] as i32) >> 16;
                        let d = &mut disp[z * 16 + y * 4 + x];
                        for i in 0..3 {
                            d[i] += t * dir[i];
                        }
                    }
                }
            }
        }
    }
    disp.map(|d| d.map(|v| (v + 32768) >> 16))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gaussians_left_out_add_nothing() {
        let (amps, sig2, table) = (amplitudes(3.0), sigma2_fixed(), table());
        let (mut kept, mut moved) = (0, 0);
        for (i, cell) in [[0, 0, 0], [-3, 7, 1], [12, -5, -9], [100, 2, -40]]
            .into_iter()
            .enumerate()
        {
            let (seed_lo, seed_hi) = (17 + i as u32, 3 * i as u32);
            let all = gaussians_around(cell, seed_lo, seed_hi, 0);
            let culled = cell_gaussians(cell, seed_lo, seed_hi, 0, sig2);
            assert!(culled.len() < all.len());
            kept += culled.len();
            for local in 0..64 {
                let p = [0, 1, 2].map(|a| cell[a] * CELL + ((local >> (2 * a)) & 3));
                let offset = offset_from(p, &all, amps, sig2, &table);
                assert_eq!(
                    offset_from(p, &culled, amps, sig2, &table),
                    offset,
                    "cell {cell:?} voxel {p:?}"
                );
                moved += (offset != [0; 3]) as usize;
                assert_eq!(
                    cell_offsets(cell, &culled, amps, sig2, &table)[local as usize],
                    offset,
                    "cell {cell:?} voxel {p:?}"
                );
            }
        }
        assert!(kept > 0 && moved > 0, "kept {kept}, moved {moved}");
    }
}
