//! The atlas in the mesh's own texture coordinates (`surface --uv own`), as Blender's and
//! Substance's bakers use them: a texel belongs to the triangle whose UV triangle holds the
//! texel's centre, and samples the 3D point with the same barycentric coordinates. A texel
//! centre on an edge shared by two triangles belongs to exactly one of them (each edge's
//! function is computed from its endpoints in one canonical order, so both triangles see the
//! same value, and a zero goes to the triangle on the edge's positive side). Texels outside
//! every triangle are filled by dilation after the bake (`super::dilate`).
//!
//! The layout is refused (naming the triangles) when two triangles cover the same texel
//! (mirrored or stacked UV islands: one texel cannot hold two points of the solid) or when a
//! texture coordinate leaves [0, 1] (tiling or UDIM layouts).

use super::bake::{Atlas, TexelLayout, MAX_ATLAS_SIDE};
use super::{Mesh, Placement};
use crate::error::{Error, Result};
use glam::DVec2;

/// How far (in texture coordinates) a corner may lie outside [0, 1] and still count as inside:
/// exporters write 1.0000001 for 1.
const UV_SLACK: f32 = 1e-4;

/// Smallest texture side chosen by default.
const MIN_DEFAULT_SIDE: u32 = 64;

impl Atlas {
    /// The atlas of `mesh`'s own texture coordinates, `texture_size` texels on a side, or when
    /// given none the power of two that gives about one texel per voxel on average (the
    /// surface's area in voxels over its area in the texture), halved until `fits` (a memory
    /// check). `what` names the mesh in errors.
    pub fn mesh_uvs(
        mesh: &Mesh,
        place: &Placement,
        texture_size: Option<u32>,
        what: &str,
        fits: impl Fn(&Atlas) -> bool,
    ) -> Result<Atlas> {
        let uvs = mesh.uvs.as_ref().ok_or_else(|| {
            Error::invalid(
                what,
                "the mesh has no texture coordinates (every corner needs one) for --uv own; \
                 leave --uv at `packed` to bake into an atlas of its own",
            )
        })?;
        for (t, corners) in uvs.iter().enumerate() {
            if let Some(c) = corners.iter().find(|c| {
                c.iter()
                    .any(|&v| !(-UV_SLACK..=1.0 + UV_SLACK).contains(&v))
            }) {
                return Err(Error::invalid(
                    what,
                    format!(
                        "triangle {t} has a texture coordinate outside [0, 1] (u {}, v {} from \
                         the top): --uv own bakes one texture (no tiling or UDIM tiles)",
                        c[0], c[1]
                    ),
                ));
            }
        }
        let layout = |side: u32| Atlas {
            width: side,
            height: side,
            texels: TexelLayout::MeshUvs,
            uvs: uvs.clone(),
            gutter: 0,
        };
        let atlas = match texture_size {
            Some(side) => {
                if !(1..=MAX_ATLAS_SIDE).contains(&side) {
                    return Err(Error::invalid(
                        format!("--texture-size {side}"),
                        format!("must be 1..={MAX_ATLAS_SIDE}"),
                    ));
                }
                let atlas = layout(side);
                if !fits(&atlas) {
                    return Err(Error::invalid(
                        format!("--texture-size {side}"),
                        "the atlas does not fit in the memory available; use a smaller size",
                    ));
                }
                atlas
            }
            None => {
                let mut side = default_side(mesh, place, uvs, what)?;
                while !fits(&layout(side)) {
                    if side <= MIN_DEFAULT_SIDE {
                        return Err(Error::invalid(
                            what,
                            "even a small texture does not fit in the memory available",
                        ));
                    }
                    side /= 2;
                }
                layout(side)
            }
        };
        atlas.check_overlaps(what)?;
        Ok(atlas)
    }

    /// Refuse a layout where two triangles cover one texel.
    fn check_overlaps(&self, what: &str) -> Result<()> {
        let mut covered = vec![0u64; (self.texel_count() as usize).div_ceil(64)];
        for t in 0..self.uvs.len() {
            let mut clash = None;
            for_each_covered_texel(self, t, |x, y, _| {
                let i = y as usize * self.width as usize + x as usize;
                if covered[i / 64] & (1 << (i % 64)) != 0 {
                    clash.get_or_insert((x, y));
                }
                covered[i / 64] |= 1 << (i % 64);
            });
            if let Some((x, y)) = clash {
                let mut first = None;
                for other in 0..t {
                    for_each_covered_texel(self, other, |ox, oy, _| {
                        if (ox, oy) == (x, y) {
                            first.get_or_insert(other);
                        }
                    });
                    if first.is_some() {
                        break;
                    }
                }
                let first = first.map_or("an earlier triangle".into(), |f| format!("triangle {f}"));
                return Err(Error::invalid(
                    what,
                    format!(
                        "its texture coordinates overlap: {first} and triangle {t} both cover \
                         texel ({x}, {y}) of the {}x{} texture (mirrored or stacked UV islands); \
                         --uv own needs every texel in at most one triangle, the packed atlas \
                         (the default) takes any mesh",
                        self.width, self.height
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// The default texture side: about one texel per voxel over the whole surface, rounded up to a
/// power of two within [`MIN_DEFAULT_SIDE`, `MAX_ATLAS_SIDE`].
fn default_side(mesh: &Mesh, place: &Placement, uvs: &[[[f32; 2]; 3]], what: &str) -> Result<u32> {
    let mut surface = 0.0f64;
    let mut texture = 0.0f64;
    for (tri, uv) in mesh.triangles.iter().zip(uvs) {
        let p = tri.map(|i| place.to_voxels(mesh.positions[i as usize]));
        surface += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let q = uv.map(|c| DVec2::new(c[0] as f64, c[1] as f64));
        texture += 0.5 * (q[1] - q[0]).perp_dot(q[2] - q[0]).abs();
    }
    if !(texture > 0.0) {
        return Err(Error::invalid(
            what,
            "its texture coordinates cover no area: every UV triangle is degenerate",
        ));
    }
    let side = (surface / texture).sqrt().ceil();
    let side =
        (side.clamp(MIN_DEFAULT_SIDE as f64, MAX_ATLAS_SIDE as f64) as u32).next_power_of_two();
    Ok(side.min(MAX_ATLAS_SIDE))
}

/// The edge function of the edge between `a` and `b` at `p`, computed with the endpoints in one
/// canonical order (lexicographic), so the two triangles sharing the edge get the same value:
/// positive on the left of the canonical direction.
fn edge(a: DVec2, b: DVec2, p: DVec2) -> f64 {
    let (from, to) = if (a.x, a.y) <= (b.x, b.y) {
        (a, b)
    } else {
        (b, a)
    };
    (to.x - from.x) * (p.y - from.y) - (to.y - from.y) * (p.x - from.x)
}

/// Every texel whose centre triangle `t` of `atlas` (a [`TexelLayout::MeshUvs`] atlas) covers,
/// as `visit(x, y, barycentric weights of the triangle's corners)`.
pub(super) fn for_each_covered_texel(
    atlas: &Atlas,
    t: usize,
    mut visit: impl FnMut(u32, u32, [f64; 3]),
) {
    let (w, h) = (atlas.width as f64, atlas.height as f64);
    let p = atlas.uvs[t].map(|c| DVec2::new(c[0] as f64 * w, c[1] as f64 * h));
    // Per corner k: the edge opposite it, and the side of that edge its interior lies on.
    let opposite = |k: usize| (p[(k + 1) % 3], p[(k + 2) % 3]);
    let side: [f64; 3] = std::array::from_fn(|k| {
        let (a, b) = opposite(k);
        edge(a, b, p[k]).signum()
    });
    if side.iter().any(|&s| s == 0.0 || s.is_nan()) {
        return; // no area: no texel
    }
    let lo = p[0].min(p[1]).min(p[2]);
    let hi = p[0].max(p[1]).max(p[2]);
    // Texel x has its centre at x + 0.5.
    let first = |v: f64| (v - 0.5).ceil().max(0.0) as u32;
    let last = |v: f64, n: u32| ((v - 0.5).floor().min(n as f64 - 1.0)).max(-1.0) as i64;
    let (x0, y0) = (first(lo.x), first(lo.y));
    let (x1, y1) = (last(hi.x, atlas.width), last(hi.y, atlas.height));
    for y in y0 as i64..=y1 {
        for x in x0 as i64..=x1 {
            let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let mut weights = [0.0; 3];
            let mut inside = true;
            for k in 0..3 {
                let (a, b) = opposite(k);
                let e = edge(a, b, c) * side[k];
                // On the edge: the texel goes to the triangle on the edge's positive side.
                if e < 0.0 || (e == 0.0 && side[k] < 0.0) {
                    inside = false;
                    break;
                }
                weights[k] = e;
            }
            if inside {
                let sum: f64 = weights.iter().sum();
                let weights = if sum > 0.0 {
                    weights.map(|e| e / sum)
                } else {
                    [1.0, 0.0, 0.0] // the centre is a corner
                };
                visit(x as u32, y as u32, weights);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A unit square of two triangles in the plane z = 0, its UVs the square itself (v down),
    /// placed at one voxel per unit.
    fn square(uvs: [[[f32; 2]; 3]; 2]) -> (Mesh, Placement) {
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [8.0, 0.0, 0.0],
                [8.0, 8.0, 0.0],
                [0.0, 8.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            uvs: Some(uvs.to_vec()),
            normals: None,
        };
        let place = Placement {
            origin: DVec3::ZERO,
            scale: 1.0,
        };
        (mesh, place)
    }

    const SQUARE_UVS: [[[f32; 2]; 3]; 2] = [
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
        [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
    ];

    #[test]
    fn every_texel_of_a_tiled_square_belongs_to_exactly_one_triangle() {
        let (mesh, place) = square(SQUARE_UVS);
        for side in [7, 8, 16] {
            let atlas = Atlas::mesh_uvs(&mesh, &place, Some(side), "sq", |_| true).unwrap();
            let mut owners = vec![0u32; (side * side) as usize];
            for t in 0..2 {
                for_each_covered_texel(&atlas, t, |x, y, w| {
                    owners[(y * side + x) as usize] += 1;
                    assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
                });
            }
            // At even sides the diagonal passes through texel centres (x + 0.5, x + 0.5): each
            // still goes to one triangle.
            assert!(owners.iter().all(|&n| n == 1), "side {side}: {owners:?}");
        }
    }

    #[test]
    fn texels_sample_the_point_with_their_barycentric_coordinates() {
        let (mesh, place) = square(SQUARE_UVS);
        let atlas = Atlas::mesh_uvs(&mesh, &place, Some(8), "sq", |_| true).unwrap();
        let points = atlas.texel_points(&mesh);
        for y in 0..8u32 {
            for x in 0..8u32 {
                let (t, p) = points[(y * 8 + x) as usize];
                assert!(t < 2);
                // u = x + 0.5 texels of 8 on a side of 8 units: the point is (x + 0.5, y + 0.5).
                let want = DVec3::new(x as f64 + 0.5, y as f64 + 0.5, 0.0);
                assert!((p - want).length() < 1e-9, "texel {x},{y}: {p}");
            }
        }
        // One texel per voxel on average by default: 8 x 8 units in the unit square, raised
        // to the smallest default side.
        let atlas = Atlas::mesh_uvs(&mesh, &place, None, "sq", |_| true).unwrap();
        assert_eq!(atlas.width, MIN_DEFAULT_SIDE);
        assert!(atlas.max_texel_step(&mesh, &place) <= 8.0 / 64.0 * 1.5);
    }

    #[test]
    fn overlapping_missing_and_out_of_range_uvs_are_refused() {
        // Both triangles mapped onto the same half of the texture.
        let stacked = [SQUARE_UVS[0], [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]];
        let (mesh, place) = square(stacked);
        let err = Atlas::mesh_uvs(&mesh, &place, Some(16), "sq.obj", |_| true)
            .unwrap_err()
            .to_string();
        assert!(err.contains("sq.obj") && err.contains("overlap"), "{err}");
        assert!(err.contains("triangle 0 and triangle 1"), "{err}");
        let (mut mesh, place) = square(SQUARE_UVS);
        mesh.uvs.as_mut().unwrap()[1][2] = [0.0, 1.5];
        let err = Atlas::mesh_uvs(&mesh, &place, Some(16), "sq.obj", |_| true)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("triangle 1") && err.contains("outside [0, 1]"),
            "{err}"
        );
        mesh.uvs = None;
        let err = Atlas::mesh_uvs(&mesh, &place, None, "sq.obj", |_| true)
            .unwrap_err()
            .to_string();
        assert!(err.contains("no texture coordinates"), "{err}");
        let (mesh, place) = square([[[0.5, 0.5]; 3]; 2]);
        let err = Atlas::mesh_uvs(&mesh, &place, None, "sq.obj", |_| true)
            .unwrap_err()
            .to_string();
        assert!(err.contains("cover no area"), "{err}");
        let (mesh, place) = square(SQUARE_UVS);
        assert!(Atlas::mesh_uvs(&mesh, &place, Some(0), "sq", |_| true).is_err());
        assert!(Atlas::mesh_uvs(&mesh, &place, Some(64), "sq", |_| false).is_err());
    }
}
