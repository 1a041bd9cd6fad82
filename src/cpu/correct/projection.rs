//! A voxel's plane projections: the 5x5 plane of exemplar a through it, gathered from the
//! neighbours' mean values and projected with E_a's PCA basis exactly as kernel `project`
//! projects exemplar neighbourhoods (16-bit multiply-adds where the weights allow, else i32).

use super::*;

impl Ctx<'_> {
    /// Projection of the plane of exemplar `a` through voxel `pos`.
    #[inline(always)]
    pub(super) fn project_plane<const MADD: bool>(
        &self,
        r: &impl Neighbours,
        pos: [i32; 3],
        a: usize,
    ) -> Projection {
        #[cfg(target_arch = "x86_64")]
        if MADD {
            if let Some(pairs) = &self.prepared.pair_weights {
                let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
                let words = r.plane_words(pos, ua, va);
                // SAFETY: MADD is only set on the AVX2 path (`correct_run_avx2`), entered after
                // detecting AVX2.
                let acc = unsafe {
                    if self.p.pca_out as usize <= 8 {
                        project_plane_madd::<1>(&words, &pairs.weights[a], &pairs.means[a])
                    } else {
                        project_plane_madd::<2>(&words, &pairs.weights[a], &pairs.means[a])
                    }
                };
                return self.finish_projection(&acc);
            }
        }
        // Accumulate only the kept dimensions (8 at the finest level, 12 above): the unused
        // weights are zero, so the result is the same; the loop is just shorter. With the
        // channel count a constant too, the compiler unrolls the channels and vectorizes the K
        // multiply-adds (integer sums: same result in any order).
        match (self.p.pca_out, self.p.ex.channels) {
            (0..=8, 3) => self.project_plane_k::<8, 3>(r, pos, a),
            (0..=8, 4) => self.project_plane_k::<8, 4>(r, pos, a),
            (9..=12, 3) => self.project_plane_k::<12, 3>(r, pos, a),
            (9..=12, 4) => self.project_plane_k::<12, 4>(r, pos, a),
            _ => self.project_plane_any(r, pos, a),
        }
    }

    /// [`Ctx::project_plane`] for K kept dimensions and C <= 4 channels (one state word).
    #[inline(always)]
    fn project_plane_k<const K: usize, const C: usize>(
        &self,
        r: &impl Neighbours,
        pos: [i32; 3],
        a: usize,
    ) -> Projection {
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let (wt, mean) = (&self.prepared.weights_t[a], &self.prepared.means[a]);
        let mut acc = [0i32; K];
        for (pixel, word) in r.plane_words(pos, ua, va).into_iter().enumerate() {
            for ch in 0..C {
                let i = pixel * C + ch;
                let centred = ((word >> (ch * 8)) & 0xFF) as i32 - mean[i];
                let row: &[i32; K] = wt[i * MAX_PCA_OUT..i * MAX_PCA_OUT + K].try_into().unwrap();
                for j in 0..K {
                    acc[j] = acc[j].wrapping_add(centred.wrapping_mul(row[j]));
                }
            }
        }
        self.finish_projection(&acc)
    }

    /// [`Ctx::project_plane`] for any channel count.
    fn project_plane_any(&self, r: &impl Neighbours, pos: [i32; 3], a: usize) -> Projection {
        let p = self.p;
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let (wt, mean) = (&self.prepared.weights_t[a], &self.prepared.means[a]);
        let mut acc = [0i32; MAX_PCA_OUT];
        let mut i = 0usize;
        for dv in -2..=2 {
            for du in -2..=2 {
                let mut n = pos;
                n[ua] += du;
                n[va] += dv;
                for ch in 0..p.ex.channels {
                    let byte = (r.word(n, ch as usize / 4) >> ((ch % 4) * 8)) & 0xFF;
                    let centred = byte as i32 - mean[i];
                    let row = &wt[i * MAX_PCA_OUT..(i + 1) * MAX_PCA_OUT];
                    for j in 0..MAX_PCA_OUT {
                        acc[j] = acc[j].wrapping_add(centred.wrapping_mul(row[j]));
                    }
                    i += 1;
                }
            }
        }
        self.finish_projection(&acc)
    }

    /// Rounds, shifts and clamps the accumulated projection to bytes (as the shader does).
    #[inline(always)]
    fn finish_projection(&self, acc: &[i32]) -> Projection {
        let p = self.p;
        let round = 1i32 << (p.shift - 1);
        let mut q = [0i16; MAX_PCA_OUT];
        for (j, &a) in acc.iter().enumerate().take(p.pca_out as usize) {
            q[j] = ((a.wrapping_add(round) >> p.shift) + 128).clamp(0, 255) as i16;
        }
        q
    }
}
