//! The per-level tables a correction scores from ([`Prepared`]): candidates with copies of their
//! projections, contiguous per source pixel, and the PCA weights paired for 16-bit multiply-adds.

use super::*;

/// A 2D candidate and a copy of its stored projection: a source pixel's k2d candidates are then
/// scored from one contiguous run instead of k2d scattered reads of the exemplar's projections.
/// P bytes of projection: the level's kept dimensions (8 at the finest level: 16-byte entries,
/// so a pixel's k2d = 2 candidates share one cache line; 12 above).
#[derive(Clone, Copy)]
pub(super) struct Candidate2d<const P: usize> {
    pub(super) coord: u32,
    /// 16 + the pixel's usage penalty: its distance's scale.
    pub(super) factor: u16,
    pub(super) projection: [u8; P],
}

/// A level's [`Candidate2d`] tables, one per distinct (list, projections).
pub(super) enum Tables2d {
    Short(Vec<Vec<Candidate2d<8>>>),
    Long(Vec<Vec<Candidate2d<12>>>),
}

/// A 3D candidate of a pixel of E_a (a triple whose a coordinate is that pixel) with copies of
/// the stored projections of its two other coordinates, E_{a+1}'s and E_{a+2}'s: what scoring
/// it needs besides the pixel's own distance, in one contiguous run per pixel.
/// P bytes per projection: the level's kept dimensions (8 at the finest level, so that its
/// entries are 32 bytes, two to a cache line; 12 above).
#[derive(Clone, Copy)]
pub(super) struct Candidate3d<const P: usize> {
    pub(super) triple: [u32; 3],
    /// 16 + the usage penalties of its three pixels: its distance's scale.
    pub(super) factor: u32,
    pub(super) next: [u8; P],
    pub(super) last: [u8; P],
}

/// A level's [`Candidate3d`] tables (see [`Prepared::candidates_3d`]).
pub(super) enum Tables3d {
    Short(Vec<Vec<Candidate3d<8>>>),
    Long(Vec<Vec<Candidate3d<12>>>),
}

impl Tables3d {
    pub(super) fn has(&self, set: usize) -> bool {
        match self {
            Tables3d::Short(t) => set < t.len(),
            Tables3d::Long(t) => set < t.len(),
        }
    }
}

/// Largest candidate table (bytes) built for one level; beyond it (large exemplars) the
/// candidates are scored from the level data directly, with the same results. A 256^2 exemplar's
/// tables fit; three 512^2 exemplars' would add ~270 MB.
pub(super) const MAX_TABLE_BYTES: usize = 32 << 20;

/// PCA weights laid out for [`project_plane_madd`]: per neighbourhood pixel (25), per channel
/// pair (0-1, 2-3), per block of 8 outputs (BLOCKS of 2), 16 i16 weights interleaved as
/// (channel 2q, output j), (channel 2q + 1, output j) for the block's 8 outputs j. Channels past
/// the exemplar's (3 colours without a feature channel) get zero weights and means.
pub(super) struct PairWeights {
    pub(super) weights: [Vec<i16>; 3],
    /// Per pixel, the 4 channels' means.
    pub(super) means: [Vec<i16>; 3],
}

pub(super) const PAIR_WEIGHTS_PER_PIXEL: usize = 2 * 2 * 16;

impl PairWeights {
    /// For one state word per voxel (3 or 4 channels), 25-pixel neighbourhoods, at most 16
    /// outputs, and weights that fit 16 bits (every analysis since revision 2); else None.
    pub(super) fn new(p: &CorrectParams, level: &[u32]) -> Option<PairWeights> {
        let channels = p.ex.channels as usize;
        let (d, k) = (p.pca_in as usize, p.pca_out as usize);
        if !(3..=4).contains(&channels) || d != 25 * channels || k > 16 || p.ex.pixel_words != 1 {
            return None;
        }
        let layout = |a: usize| -> Option<(Vec<i16>, Vec<i16>)> {
            let (w0, m0) = (
                [p.weights0, p.weights1, p.weights2][a] as usize,
                [p.mean0, p.mean1, p.mean2][a] as usize,
            );
            let mut weights = vec![0i16; 25 * PAIR_WEIGHTS_PER_PIXEL];
            let mut means = vec![0i16; 25 * 4];
            for pixel in 0..25 {
                for ch in 0..channels {
                    let input = pixel * channels + ch;
                    means[pixel * 4 + ch] = i16::try_from(level[m0 + input] as i32).ok()?;
                    let (pair, lane) = (ch / 2, ch % 2);
                    for j in 0..k {
                        let w = i16::try_from(level[w0 + j * d + input] as i32).ok()?;
                        let slot = pixel * PAIR_WEIGHTS_PER_PIXEL + (pair * 2 + j / 8) * 16;
                        weights[slot + (j % 8) * 2 + lane] = w;
                    }
                }
            }
            Some((weights, means))
        };
        let (w0, m0) = layout(0)?;
        let (w1, m1) = layout(1)?;
        let (w2, m2) = layout(2)?;
        Some(PairWeights {
            weights: [w0, w1, w2],
            means: [m0, m1, m2],
        })
    }
}

/// What a correction derives from a level's data alone: the PCA weights transposed, the means,
/// and the 2D candidate tables. The same for every sub-pass of a level, so an executor builds
/// it once per level ([`correct_prepared`]).
pub struct Prepared {
    /// The parameters it was built from (the level-data offsets and sizes it depends on).
    pub(super) key: [u32; 29],
    /// Per exemplar: the PCA weights transposed to input-major (input_dims x MAX_PCA_OUT, zero
    /// padded) and the mean, so the inner loop is contiguous. Integer sums do not depend on the
    /// order of accumulation, so the results equal the shader's bit for bit.
    pub(super) weights_t: [Vec<i32>; 3],
    pub(super) means: [Vec<i32>; 3],
    /// The same weights for the AVX2 path's 16-bit multiply-adds, when they fit.
    pub(super) pair_weights: Option<PairWeights>,
    /// Per exemplar, an index into `candidates_2d` (exemplars sharing their lists share a table),
    /// or None when the projections are too long for [`Candidate2d`] or the tables too large.
    pub(super) candidates_2d_of: [Option<usize>; 3],
    /// `k2d` [`Candidate2d`] per exemplar pixel, row-major.
    pub(super) candidates_2d: Tables2d,
    /// Per candidate set (one when shared), `k3d_used` [`Candidate3d`] per pixel (slots past
    /// the pixel's count unused); empty when the projections are too long, or a shared set's
    /// exemplars do not share their projections.
    pub(super) candidates_3d: Tables3d,
}

impl Prepared {
    pub(super) fn key(p: &CorrectParams) -> [u32; 29] {
        [
            p.weights0,
            p.weights1,
            p.weights2,
            p.mean0,
            p.mean1,
            p.mean2,
            p.cand2d0,
            p.cand2d1,
            p.cand2d2,
            p.proj0,
            p.proj1,
            p.proj2,
            p.pca_in,
            p.pca_out,
            p.k2d,
            p.ex.width,
            p.ex.height,
            p.proj_words,
            p.counts0,
            p.counts1,
            p.counts2,
            p.cand3d0,
            p.cand3d1,
            p.cand3d2,
            p.k3d_used ^ (p.k3d_stride << 8) ^ (p.shared_sets << 16),
            // The penalties follow the pixels (the candidate tables hold them).
            p.ex.pixels0,
            p.ex.pixels1,
            p.ex.pixels2,
            p.ex.pixel_words,
        ]
    }

    /// The [`Candidate3d`] tables (see the field).
    pub(super) fn candidates_3d<const P: usize>(
        p: &CorrectParams,
        level: &[u32],
    ) -> Vec<Vec<Candidate3d<P>>> {
        let k = p.pca_out as usize;
        let proj = [p.proj0, p.proj1, p.proj2];
        let sets = if p.shared_sets != 0 { 1 } else { 3 };
        let bytes = sets
            * (p.ex.width * p.ex.height * p.k3d_used) as usize
            * std::mem::size_of::<Candidate3d<P>>();
        if k != P
            || bytes > MAX_TABLE_BYTES
            || (p.shared_sets != 0 && (proj[1] != proj[0] || proj[2] != proj[0]))
        {
            return Vec::new();
        }
        let level_bytes: &[u8] = bytemuck::cast_slice(level);
        let projection = |e: usize, c: u32| {
            let (x, y) = coord(c);
            let base = (proj[e] + (y as u32 * p.ex.width + x as u32) * p.proj_words) as usize * 4;
            let mut out = [0u8; P];
            out[..k].copy_from_slice(&level_bytes[base..base + k]);
            out
        };
        let used = p.k3d_used as usize;
        (0..sets)
            .map(|set| {
                let counts = [p.counts0, p.counts1, p.counts2][set] as usize;
                let list = [p.cand3d0, p.cand3d1, p.cand3d2][set] as usize;
                let (next, last) = ((set + 1) % 3, (set + 2) % 3);
                (0..(p.ex.width * p.ex.height) as usize)
                    .into_par_iter()
                    .flat_map_iter(|pixel| {
                        let count = (level[counts + pixel] as usize).min(used);
                        (0..used).map(move |j| {
                            if j >= count {
                                return Candidate3d {
                                    triple: [0; 3],
                                    factor: 0,
                                    next: [0; P],
                                    last: [0; P],
                                };
                            }
                            let e = list + (pixel * p.k3d_stride as usize + j) * 3;
                            let triple = [level[e], level[e + 1], level[e + 2]];
                            Candidate3d {
                                triple,
                                factor: 16
                                    + (0..3).map(|e| penalty(p, level, e, triple[e])).sum::<u32>(),
                                next: projection(next, triple[next]),
                                last: projection(last, triple[last]),
                            }
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// The [`Candidate2d`] tables (see the fields), empty when the projections are not P long
    /// or the tables too large.
    #[allow(clippy::type_complexity)]
    pub(super) fn candidates_2d<const P: usize>(
        p: &CorrectParams,
        level: &[u32],
    ) -> ([Option<usize>; 3], Vec<Vec<Candidate2d<P>>>) {
        let level_bytes: &[u8] = bytemuck::cast_slice(level);
        let mut candidates_2d: Vec<Vec<Candidate2d<P>>> = Vec::new();
        let mut candidates_2d_of = [None; 3];
        let mut built: Vec<(u32, u32, u32)> = Vec::new();
        let k = p.pca_out as usize;
        let table_bytes =
            (p.ex.width * p.ex.height * p.k2d) as usize * std::mem::size_of::<Candidate2d<P>>();
        if k == P && 3 * table_bytes <= MAX_TABLE_BYTES {
            for a in 0..3 {
                let (list, proj) = (
                    [p.cand2d0, p.cand2d1, p.cand2d2][a],
                    [p.proj0, p.proj1, p.proj2][a],
                );
                let pixels = [p.ex.pixels0, p.ex.pixels1, p.ex.pixels2][a];
                if let Some(i) = built.iter().position(|&b| b == (list, proj, pixels)) {
                    candidates_2d_of[a] = Some(i);
                    continue;
                }
                let n = (p.ex.width * p.ex.height * p.k2d) as usize;
                let table = level[list as usize..list as usize + n]
                    .par_iter()
                    .map(|&c| {
                        let (x, y) = coord(c);
                        let base =
                            (proj + (y as u32 * p.ex.width + x as u32) * p.proj_words) as usize * 4;
                        let mut projection = [0u8; P];
                        projection[..k].copy_from_slice(&level_bytes[base..base + k]);
                        Candidate2d {
                            coord: c,
                            factor: (16 + penalty(p, level, a, c)) as u16,
                            projection,
                        }
                    })
                    .collect();
                candidates_2d_of[a] = Some(candidates_2d.len());
                candidates_2d.push(table);
                built.push((list, proj, pixels));
            }
        }
        (candidates_2d_of, candidates_2d)
    }

    pub fn new(p: &CorrectParams, level: &[u32]) -> Prepared {
        let transpose = |a: usize| {
            let (w0, m0) = (
                [p.weights0, p.weights1, p.weights2][a] as usize,
                [p.mean0, p.mean1, p.mean2][a] as usize,
            );
            let (d, k) = (p.pca_in as usize, p.pca_out as usize);
            let mut t = vec![0i32; d * MAX_PCA_OUT];
            for i in 0..d {
                for j in 0..k {
                    t[i * MAX_PCA_OUT + j] = level[w0 + j * d + i] as i32;
                }
            }
            (
                t,
                level[m0..m0 + d]
                    .iter()
                    .map(|&m| m as i32)
                    .collect::<Vec<i32>>(),
            )
        };
        let (t0, m0) = transpose(0);
        let (t1, m1) = transpose(1);
        let (t2, m2) = transpose(2);
        let (candidates_2d_of, candidates_2d) = match p.pca_out {
            8 => {
                let (of, t) = Self::candidates_2d::<8>(p, level);
                (of, Tables2d::Short(t))
            }
            _ => {
                let (of, t) = Self::candidates_2d::<12>(p, level);
                (of, Tables2d::Long(t))
            }
        };
        Prepared {
            key: Self::key(p),
            weights_t: [t0, t1, t2],
            means: [m0, m1, m2],
            pair_weights: PairWeights::new(p, level),
            candidates_2d_of,
            candidates_2d,
            candidates_3d: match p.pca_out {
                8 => Tables3d::Short(Self::candidates_3d::<8>(p, level)),
                _ => Tables3d::Long(Self::candidates_3d::<12>(p, level)),
            },
        }
    }

    /// Without the candidate tables: every candidate scored from the level data directly, as
    /// for exemplars too large for the tables (the same results; tests compare the two).
    #[cfg(any(test, feature = "internals"))]
    pub fn without_tables(mut self) -> Prepared {
        self.candidates_2d_of = [None; 3];
        self.candidates_2d = Tables2d::Short(Vec::new());
        self.candidates_3d = Tables3d::Short(Vec::new());
        self
    }

    /// Whether it was built for a level laid out as `p` says.
    pub fn fits(&self, p: &CorrectParams) -> bool {
        self.key == Self::key(p)
    }
}
