//! The packed atlas layouts: one rectangular cell per triangle, either the same square for every
//! triangle ([`Atlas::new`], `--texels`) or sized to its triangle ([`Atlas::fitted`],
//! `--texel-size`), shelf-packed, each cell with an optional gutter of texels around it that the
//! bake fills by dilation (so mip levels do not mix cells).

use super::bake::{Atlas, Cell, MAX_ATLAS_SIDE};
use super::{Mesh, Placement};
use crate::error::{Error, Result};
use glam::DVec3;

impl Atlas {
    /// Every one of `triangles` gets a square cell of `texels`^2, in a grid of ceil(sqrt(n))
    /// columns (`--texels`), with `gutter` texels of room on every side of each cell.
    pub fn new(triangles: usize, texels: u32, gutter: u32) -> Result<Atlas> {
        if !(2..=256).contains(&texels) {
            return Err(Error::invalid(
                format!("--texels {texels}"),
                "must be 2..=256",
            ));
        }
        let cols = (triangles as f64).sqrt().ceil().max(1.0) as u32;
        let rows = (triangles as u32).div_ceil(cols).max(1);
        let pitch = texels as u64 + 2 * gutter as u64;
        let (width, height) = (cols as u64 * pitch, rows as u64 * pitch);
        if width > MAX_ATLAS_SIDE as u64 || height > MAX_ATLAS_SIDE as u64 {
            return Err(Error::invalid(
                format!("--texels {texels}"),
                format!(
                    "{triangles} triangles need a {width}x{height} atlas, over the \
                     {MAX_ATLAS_SIDE} limit; use fewer texels per triangle"
                ),
            ));
        }
        let cells = (0..triangles as u32)
            .map(|k| Cell {
                x: (k % cols) * pitch as u32 + gutter,
                y: (k / cols) * pitch as u32 + gutter,
                width: texels,
                height: texels,
                first: 0,
            })
            .collect();
        Ok(Atlas::with_cells(
            width as u32,
            height as u32,
            cells,
            gutter,
        ))
    }

    /// Cells sized to their triangles: a step of at most `texel_size` voxels along both of a
    /// cell's edges (so every point of the triangle lies within one texel size of a texel's
    /// point), each triangle's right-angle corner put where its cell is smallest, the cells
    /// shelf-packed (tallest first) into a near-square atlas. `None` when the atlas would pass
    /// [`MAX_ATLAS_SIDE`], the texel size is not a positive number or the mesh does not pass
    /// [`Mesh::validate`] ([`Self::fitted_within`] says which). Each cell has `gutter` texels of
    /// room on every side.
    pub fn fitted(mesh: &Mesh, place: &Placement, texel_size: f64, gutter: u32) -> Option<Atlas> {
        if !(texel_size > 0.0 && texel_size.is_finite()) || mesh.validate("mesh").is_err() {
            return None;
        }
        let texels_along = |from: DVec3, to: DVec3| {
            // At least 2 (the cell's corners); beyond the limit stays beyond it.
            let steps = ((to - from).length() / texel_size).ceil();
            (steps + 1.0).clamp(2.0, MAX_ATLAS_SIDE as f64 + 1.0) as u32
        };
        let sizes: Vec<(u32, u32, u8)> = mesh
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| place.to_voxels(mesh.positions[i as usize]));
                (0..3u8)
                    .map(|f| {
                        let cell = Cell {
                            x: 0,
                            y: 0,
                            width: 0,
                            height: 0,
                            first: f,
                        };
                        let [a, b, c] = cell.ordered(p);
                        (texels_along(a, b), texels_along(a, c), f)
                    })
                    .min_by_key(|&(w, h, f)| (w as u64 * h as u64, f))
                    .expect("three corners")
            })
            .collect();
        if sizes
            .iter()
            .any(|&(w, h, _)| w > MAX_ATLAS_SIDE || h > MAX_ATLAS_SIDE)
        {
            return None;
        }
        let padded: Vec<[u32; 2]> = sizes
            .iter()
            .map(|&(w, h, _)| [w, h].map(|side| side.saturating_add(2 * gutter)))
            .collect();
        let (width, height, corners) = shelf_pack(&padded)?;
        let cells = sizes
            .iter()
            .zip(corners)
            .map(|(&(width, height, first), [x, y])| Cell {
                x: x + gutter,
                y: y + gutter,
                width,
                height,
                first,
            })
            .collect();
        Some(Atlas::with_cells(width, height, cells, gutter))
    }

    /// [`Self::fitted`] at `texel_size`, or when given none, at one voxel per texel grown by
    /// 1.25x until the atlas fits [`MAX_ATLAS_SIDE`] and `fits` (a memory check); returns the
    /// atlas and the texel size used.
    pub fn fitted_within(
        mesh: &Mesh,
        place: &Placement,
        texel_size: Option<f64>,
        gutter: u32,
        fits: impl Fn(&Atlas) -> bool,
    ) -> Result<(Atlas, f64)> {
        mesh.validate("mesh")?;
        if let Some(size) = texel_size {
            if !(size > 0.0 && size.is_finite()) {
                return Err(Error::invalid(
                    format!("--texel-size {size}"),
                    "must be a positive number of voxels",
                ));
            }
            return match Atlas::fitted(mesh, place, size, gutter) {
                Some(atlas) => Ok((atlas, size)),
                None => Err(Error::invalid(
                    format!("--texel-size {size}"),
                    format!(
                        "the atlas would pass {MAX_ATLAS_SIDE} texels on a side; use a larger \
                         texel size"
                    ),
                )),
            };
        }
        // Beyond the mesh's diagonal every cell is at its smallest (2 x 2): no use growing.
        let (lo, hi) = mesh.bounds();
        let diagonal = (hi - lo).length() * place.scale;
        let mut size = 1.0f64;
        loop {
            if let Some(atlas) = Atlas::fitted(mesh, place, size, gutter) {
                if fits(&atlas) {
                    return Ok((atlas, size));
                }
            }
            // (Also ends the loop for a mesh without finite bounds.)
            if !(size <= diagonal) {
                return Err(Error::invalid(
                    "the mesh",
                    format!(
                        "its {} triangles do not fit an atlas of at most {MAX_ATLAS_SIDE} \
                         texels on a side within the memory available, even at 2 x 2 texels \
                         each",
                        mesh.triangles.len()
                    ),
                ));
            }
            size *= 1.25;
        }
    }
}

/// Shelf packing: rectangles `sizes` (width, height), tallest first (then widest, then by
/// index: deterministic), placed left to right in rows as wide as a square of their total area
/// would be, widened once to make the result near-square. Returns the atlas width and height
/// and each rectangle's top-left corner; `None` when a side passes [`MAX_ATLAS_SIDE`].
fn shelf_pack(sizes: &[[u32; 2]]) -> Option<(u32, u32, Vec<[u32; 2]>)> {
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by_key(|&k| {
        (
            std::cmp::Reverse(sizes[k][1]),
            std::cmp::Reverse(sizes[k][0]),
            k,
        )
    });
    let widest = sizes.iter().map(|s| s[0] as u64).max().unwrap_or(1);
    let area: u64 = sizes.iter().map(|s| s[0] as u64 * s[1] as u64).sum();
    let pack = |row_width: u64| {
        let mut corners = vec![[0u32; 2]; sizes.len()];
        let (mut x, mut y, mut shelf) = (0u64, 0u64, 0u64);
        for &k in &order {
            let [w, h] = sizes[k].map(u64::from);
            if x + w > row_width {
                (x, y, shelf) = (0, y + shelf, 0);
            }
            corners[k] = [x as u32, y as u32];
            x += w;
            shelf = shelf.max(h);
        }
        (y + shelf, corners)
    };
    let first_width = widest.max((area as f64).sqrt().ceil() as u64);
    let (first_height, _) = pack(first_width);
    // Shelves waste the space above their shorter cells; widen the rows so the atlas comes
    // out about square.
    let width = widest.max(((first_width * first_height) as f64).sqrt().ceil() as u64);
    let (height, corners) = pack(width);
    if width > MAX_ATLAS_SIDE as u64 || height > MAX_ATLAS_SIDE as u64 {
        return None;
    }
    let used = corners
        .iter()
        .zip(sizes)
        .map(|(c, s)| c[0] as u64 + s[0] as u64)
        .max()
        .unwrap_or(1);
    Some((used.max(1) as u32, height.max(1) as u32, corners))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Mesh {
        Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
            uvs: None,
            normals: None,
        }
    }

    #[test]
    fn texels_sample_points_on_their_triangle() {
        let mesh = tetra();
        let place = Placement::fit(&mesh, 64);
        let atlas = Atlas::new(4, 8, 0).unwrap();
        assert_eq!((atlas.width, atlas.height), (16, 16));
        let voxels = atlas.texel_voxels(&mesh, &place);
        // Triangle 1 (cell (1, 0)), vertices 0, 1, 3, lies in the plane y = 0.
        for j in 0..8 {
            for i in 8..16 {
                assert_eq!(voxels[j * 16 + i][1], 0, "texel ({i}, {j})");
            }
        }
        // Corner texels sample the corners exactly.
        assert_eq!(voxels[0], [0, 0, 0]);
        // Triangle 0's b is vertex 2 = (0, 1, 0), at y = 64 - epsilon.
        assert_eq!(voxels[7], [0, 63, 0]);
        // Every texel lies in the mesh's box.
        assert!(voxels
            .iter()
            .all(|v| v.iter().all(|&c| (0..64).contains(&c))));
        // The uvs of a cell's corners land on the centres of its corner texels.
        let uv = atlas.uvs[3];
        assert_eq!(uv[0], [8.5 / 16.0, 8.5 / 16.0]);
        assert_eq!(uv[1], [15.5 / 16.0, 8.5 / 16.0]);
    }

    #[test]
    fn oversized_atlases_are_refused() {
        assert!(Atlas::new(10_000_000, 64, 0).is_err());
        assert!(Atlas::new(10, 1, 0).is_err());
    }

    /// Seeded uniform numbers in [0, 1) (the same every run).
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A mesh of very unequal triangles in voxel units (placement scale 1): a large one (200
    /// voxels on a side), a thin obtuse sliver, tiny ones, a degenerate one and two needles.
    fn unequal() -> (Mesh, Placement) {
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [200.0, 0.0, 0.0],
                [0.0, 0.0, 200.0],
                [0.0, 150.0, 0.0],
                [90.0, 151.5, 3.0],
                [180.0, 150.0, 0.0],
                [10.0, 10.0, 10.0],
                [10.6, 10.1, 10.0],
                [10.0, 10.7, 10.3],
                [0.0, 300.0, 0.0],
                [100.0, 300.0, 0.0],
                [0.0, 301.0, 0.0],
                [0.0, 400.0, 0.0],
                [40.0, 400.0, 0.0],
                [0.0, 410.0, 0.0],
            ],
            // The last two: right-angled needles (100 x 1 and 40 x 10 voxels), whose cells are
            // long rectangles.
            triangles: vec![
                [0, 1, 2],
                [3, 4, 5],
                [6, 7, 8],
                [8, 6, 7],
                [6, 6, 7],
                [9, 10, 11],
                [12, 13, 14],
            ],
            uvs: None,
            normals: None,
        };
        let place = Placement {
            origin: DVec3::ZERO,
            scale: 1.0,
        };
        (mesh, place)
    }

    #[test]
    fn fitted_cells_sample_every_point_of_their_triangle_within_a_texel_size() {
        let (mesh, place) = unequal();
        for size in [1.0, 2.5] {
            let atlas = Atlas::fitted(&mesh, &place, size, 0).unwrap();
            // The large triangle gets a cell of its own size (square cells of the median edge
            // sampled it 30 times more coarsely).
            let big = atlas.cells()[0];
            assert_eq!(
                (big.width, big.height),
                (
                    (200.0 / size).ceil() as u32 + 1,
                    (200.0 / size).ceil() as u32 + 1
                )
            );
            let points = atlas.texel_points(&mesh);
            let mut next = uniform(12345);
            for (k, (tri, cell)) in mesh.triangles.iter().zip(atlas.cells()).enumerate() {
                let corners = tri.map(|i| place.to_voxels(mesh.positions[i as usize]));
                let texels: Vec<DVec3> = (0..cell.height)
                    .flat_map(|j| (0..cell.width).map(move |i| (i, j)))
                    .map(|(i, j)| points[atlas.texel_index(cell, i, j)])
                    .inspect(|&(t, _)| assert_eq!(t, k as u32))
                    .map(|(_, p)| p)
                    .collect();
                for _ in 0..300 {
                    let (mut s, mut t) = (next(), next());
                    if s + t > 1.0 {
                        (s, t) = (1.0 - s, 1.0 - t);
                    }
                    let q =
                        corners[0] + s * (corners[1] - corners[0]) + t * (corners[2] - corners[0]);
                    let nearest = texels
                        .iter()
                        .map(|p| (*p - q).length())
                        .fold(f64::INFINITY, f64::min);
                    assert!(
                        nearest <= size + 1e-9,
                        "triangle {k}, size {size}: {nearest}"
                    );
                }
            }
        }
    }

    /// What a renderer shows: the bilinear blend of the four texels around a point's texel
    /// coordinates is that point, to within half a texel size, also next to the long edge of
    /// a needle's rectangle (where texels beyond the hypotenuse take points of the edge).
    #[test]
    fn bilinear_filtering_of_fitted_cells_reproduces_the_surface() {
        let (mesh, place) = unequal();
        for size in [1.0, 2.5] {
            let atlas = Atlas::fitted(&mesh, &place, size, 0).unwrap();
            assert_eq!(
                (atlas.cells()[5].width, atlas.cells()[5].height),
                ((100.0 / size).ceil() as u32 + 1, 2)
            );
            assert_eq!(
                (atlas.cells()[6].width, atlas.cells()[6].height),
                (
                    (40.0 / size).ceil() as u32 + 1,
                    (10.0 / size).ceil() as u32 + 1
                )
            );
            let points = atlas.texel_points(&mesh);
            let mut next = uniform(99);
            for (k, (tri, cell)) in mesh.triangles.iter().zip(atlas.cells()).enumerate() {
                let corners = tri.map(|i| place.to_voxels(mesh.positions[i as usize]));
                let [a, b, c] = cell.ordered(corners);
                let texel = |i: u32, j: u32| points[atlas.texel_index(cell, i, j)].1;
                for _ in 0..500 {
                    let (mut s, mut t) = (next(), next());
                    if s + t > 1.0 {
                        (s, t) = (1.0 - s, 1.0 - t);
                    }
                    let want = a + s * (b - a) + t * (c - a);
                    let x = s * (cell.width - 1) as f64;
                    let y = t * (cell.height - 1) as f64;
                    let (i, j) = (x.floor() as u32, y.floor() as u32);
                    let (i1, j1) = ((i + 1).min(cell.width - 1), (j + 1).min(cell.height - 1));
                    let (fx, fy) = (x - i as f64, y - j as f64);
                    let got = (texel(i, j) * (1.0 - fx) + texel(i1, j) * fx) * (1.0 - fy)
                        + (texel(i, j1) * (1.0 - fx) + texel(i1, j1) * fx) * fy;
                    let error = (got - want).length();
                    assert!(
                        error <= 0.5 * size,
                        "triangle {k}, size {size}: {error} at s {s} t {t}"
                    );
                }
            }
        }
    }

    #[test]
    fn fitted_cells_are_disjoint_inside_the_atlas_and_their_uvs_hit_the_corners() {
        let (mesh, place) = unequal();
        let atlas = Atlas::fitted(&mesh, &place, 1.0, 0).unwrap();
        let mut owner = vec![usize::MAX; atlas.texel_count() as usize];
        for (k, cell) in atlas.cells().iter().enumerate() {
            assert!(cell.width >= 2 && cell.height >= 2);
            assert!(cell.x + cell.width <= atlas.width && cell.y + cell.height <= atlas.height);
            for j in 0..cell.height {
                for i in 0..cell.width {
                    let t = atlas.texel_index(cell, i, j);
                    assert_eq!(owner[t], usize::MAX, "texel of cells {} and {k}", owner[t]);
                    owner[t] = k;
                }
            }
        }
        // Each corner's uv is the centre of the texel whose point is that corner.
        let points = atlas.texel_points(&mesh);
        for (k, tri) in mesh.triangles.iter().enumerate() {
            for (corner, uv) in tri.iter().zip(atlas.uvs[k]) {
                let x = (uv[0] * atlas.width as f32 - 0.5).round() as usize;
                let y = (uv[1] * atlas.height as f32 - 0.5).round() as usize;
                let want = place.to_voxels(mesh.positions[*corner as usize]);
                let (_, got) = points[y * atlas.width as usize + x];
                assert!(
                    (got - want).length() < 1e-9,
                    "triangle {k}: {got} vs {want}"
                );
            }
        }
        // The sliver's cell runs along its long edges (its obtuse corner first), not 180 x 180.
        let sliver = atlas.cells()[1];
        assert!(
            sliver.width as u64 * sliver.height as u64 <= 95 * 95,
            "{sliver:?}"
        );
    }

    #[test]
    fn shelf_packing_is_disjoint_and_near_square() {
        let mut seed = 7u32;
        let sizes: Vec<[u32; 2]> = (0..500)
            .map(|_| {
                seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
                [2 + (seed >> 8) % 40, 2 + (seed >> 20) % 40]
            })
            .collect();
        let (w, h, corners) = shelf_pack(&sizes).unwrap();
        let mut used = vec![false; w as usize * h as usize];
        for (c, s) in corners.iter().zip(&sizes) {
            assert!(c[0] + s[0] <= w && c[1] + s[1] <= h);
            for y in c[1]..c[1] + s[1] {
                for x in c[0]..c[0] + s[0] {
                    assert!(!std::mem::replace(&mut used[(y * w + x) as usize], true));
                }
            }
        }
        let area: u64 = sizes.iter().map(|s| s[0] as u64 * s[1] as u64).sum();
        let fill = area as f64 / (w as f64 * h as f64);
        assert!(fill > 0.7, "{w}x{h}: {fill}");
        assert!(w <= 2 * h && h <= 2 * w, "{w}x{h}");
    }

    #[test]
    fn the_default_texel_size_grows_until_the_atlas_fits() {
        let (mesh, place) = unequal();
        let (atlas, size) =
            Atlas::fitted_within(&mesh, &place, None, 0, |a| a.texel_count() <= 100 * 100).unwrap();
        assert!(size > 1.0 && atlas.texel_count() <= 100 * 100, "{size}");
        let smaller = Atlas::fitted(&mesh, &place, size / 1.25, 0).unwrap();
        assert!(smaller.texel_count() > 100 * 100);
        // A given texel size is kept or refused, never changed.
        let (_, kept) = Atlas::fitted_within(&mesh, &place, Some(1.0), 0, |_| false).unwrap();
        assert_eq!(kept, 1.0);
        assert!(Atlas::fitted_within(&mesh, &place, Some(0.001), 0, |_| true).is_err());
        assert!(Atlas::fitted_within(&mesh, &place, Some(f64::NAN), 0, |_| true).is_err());
        // Nothing fits: an error, not a loop.
        assert!(Atlas::fitted_within(&mesh, &place, None, 0, |_| false).is_err());
    }
}
