//! Bake the solid onto a mesh's surface and look at it: the atlas, then a small z-buffered
//! rasterizer (orthographic, head-on light) that draws the mesh textured by it into a PNG.
//! `cargo run --release --example 06_render_surface -- [MESH] [OUT.png] [RESOLUTION]`
//! (default: the octahedron, render.png, 96).
use glam::{Vec2, Vec3};
use solidsynth::solid::surface::{AtlasLayout, SurfacePlan};
use solidsynth::Solid;

const SIZE: usize = 384;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let octahedron = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/octahedron.obj");
    let path = args
        .next()
        .filter(|p| !p.is_empty())
        .unwrap_or_else(|| octahedron.into());
    let out = args.next().unwrap_or_else(|| "render.png".into());
    let resolution: u32 = args.next().map(|r| r.parse()).transpose()?.unwrap_or(96);
    let mesh = solidsynth::mesh::load(path.as_ref())?;
    let plan = SurfacePlan::new(
        &mesh,
        "bunny.obj",
        resolution,
        AtlasLayout::TexelSize {
            size: None,
            gutter: 0,
        },
        None,
        128,
    )?;
    let baked = Solid::builder()
        .seed(5)
        .cpu()
        .build()?
        .bake_surface(&mesh, &plan)?;
    // Camera: azimuth 30 degrees about +y, elevation 20; the mesh fitted into the image.
    let (az, el) = (30f32.to_radians(), 20f32.to_radians());
    let to_eye = Vec3::new(az.sin() * el.cos(), el.sin(), az.cos() * el.cos());
    let right = Vec3::Y.cross(to_eye).normalize();
    let up = to_eye.cross(right);
    let points: Vec<Vec3> = mesh.positions.iter().map(|&p| Vec3::from(p)).collect();
    let (lo, hi) = points
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(l, h), &p| (l.min(p), h.max(p)));
    let (centre, radius) = ((lo + hi) / 2.0, (hi - lo).length() / 2.0);
    let scale = SIZE as f32 / (2.05 * radius);
    let screen = |p: Vec3| {
        let d = p - centre;
        Vec3::new(
            SIZE as f32 / 2.0 + d.dot(right) * scale,
            SIZE as f32 / 2.0 - d.dot(up) * scale,
            d.dot(to_eye),
        )
    };
    let mut depth = vec![f32::NEG_INFINITY; SIZE * SIZE];
    let mut image = image::RgbImage::from_pixel(SIZE as u32, SIZE as u32, image::Rgb([40, 40, 48]));
    for (t, uvs) in mesh.triangles.iter().zip(&plan.atlas.uvs) {
        let [a, b, c] = t.map(|i| screen(points[i as usize]));
        let normal = (points[t[1] as usize] - points[t[0] as usize])
            .cross(points[t[2] as usize] - points[t[0] as usize])
            .normalize_or_zero();
        let light = 0.35 + 0.65 * normal.dot(to_eye).abs();
        let area = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        if area.abs() < 1e-9 {
            continue;
        }
        let (x0, x1) = (
            a.x.min(b.x).min(c.x).max(0.0) as usize,
            a.x.max(b.x).max(c.x).min(SIZE as f32 - 1.0) as usize,
        );
        let (y0, y1) = (
            a.y.min(b.y).min(c.y).max(0.0) as usize,
            a.y.max(b.y).max(c.y).min(SIZE as f32 - 1.0) as usize,
        );
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let w0 = ((b.x - px) * (c.y - py) - (c.x - px) * (b.y - py)) / area;
                let w1 = ((c.x - px) * (a.y - py) - (a.x - px) * (c.y - py)) / area;
                let w2 = 1.0 - w0 - w1;
                let z = w0 * a.z + w1 * b.z + w2 * c.z;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 || z <= depth[y * SIZE + x] {
                    continue;
                }
                depth[y * SIZE + x] = z;
                let uv =
                    Vec2::from(uvs[0]) * w0 + Vec2::from(uvs[1]) * w1 + Vec2::from(uvs[2]) * w2;
                let tx = ((uv.x * baked.width as f32) as u32).min(baked.width - 1);
                let ty = ((uv.y * baked.height as f32) as u32).min(baked.height - 1);
                let texel = (ty * baked.width + tx) as usize * baked.texel_bytes;
                let rgb = [0, 1, 2].map(|k| (baked.pixels[texel + k] as f32 * light) as u8);
                image.put_pixel(x as u32, y as u32, image::Rgb(rgb));
            }
        }
    }
    image.save(&out)?;
    println!(
        "{} triangles, a {}x{} atlas, rendered -> {out}",
        mesh.triangles.len(),
        baked.width,
        baked.height
    );
    Ok(())
}
