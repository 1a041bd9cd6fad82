//! `lapped_render` (a render pipeline): the GPU image of an LST model's surface against a CPU
//! ray cast of the same camera ([`reference_pixel`]): same coverage away from the silhouette,
//! colours within a named tolerance; the comparison is shown to fail for a moved camera.

use solidsynth::cpu::lapped_render::reference_pixel;
use solidsynth::gpu::lapped_render::render;
use solidsynth::lapped::camera::Camera;
use solidsynth::lapped::exemplar::SolidExemplar;
use solidsynth::lapped::field::Constraints;
use solidsynth::lapped::model::LstModel;
use solidsynth::lapped::{self, shapes, FillOptions};
use solidsynth::volume::Volume;

/// Mean absolute error allowed, in 8-bit levels per channel: the GPU blends into an RGBA8 target
/// (each of the ~10 layers rounds to 8 bits), filters textures with reduced-precision weights
/// (lavapipe: 8 bits of sub-texel position) and interpolates in f32; the CPU stops compositing
/// once coverage is within 1/512 of opaque.
const MEAN_TOLERANCE: f64 = 2.0;
/// Pixels (fraction of those compared) allowed beyond `PIXEL_TOLERANCE` levels: pixels whose
/// centre falls within rounding of a mask edge or a triangle edge.
const OUTLIER_FRACTION: f64 = 0.02;
const PIXEL_TOLERANCE: f64 = 12.0;

fn model() -> LstModel {
    let n = 16u32;
    let mut v = Volume::new(n, n, n, 3);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let c = v.at_mut(x, y, z);
                c[0] = (x * 15) as u8;
                c[1] = (y * 15) as u8;
                c[2] = 255 - (z * 15) as u8;
            }
        }
    }
    let e = SolidExemplar::from_volume(&v, "e").unwrap();
    let c = Constraints::parse(br#"{"type": "0"}"#, "c").unwrap();
    let opts = FillOptions {
        resolution: 6,
        ..Default::default()
    };
    let mesh = shapes::sphere(32, 16);
    lapped::build(
        lapped::FillInputs {
            mesh: &mesh,
            mesh_name: "sphere",
            exemplar: e,
            exemplar_source: "e",
            constraints: &c,
            constraints_name: "c",
        },
        &opts,
        &|_, _| {},
    )
    .unwrap()
    .0
}

/// Compare a GPU image with the CPU reference of `camera`; Err describes the mismatch.
fn compare(model: &LstModel, gpu: &image::RgbaImage, camera: &Camera) -> Result<String, String> {
    let size = gpu.width();
    let faces = model.mesh.boundary_faces(&model.mesh.face_neighbors());
    let normals = model.mesh.surface_normals(&faces);
    let (mut compared, mut outliers, mut total) = (0usize, 0usize, 0.0f64);
    let mut coverage_mismatch = 0usize;
    for y in 0..size {
        for x in 0..size {
            let reference = reference_pixel(
                &model.mesh.vertices,
                &faces,
                &normals,
                camera,
                size,
                x,
                y,
                |tet, hit| {
                    let b = model
                        .mesh
                        .barycentric(tet as usize, hit)
                        .map(|x| x.max(0.0));
                    let sum: f64 = b.iter().sum();
                    model.shade(tet as usize, b.map(|x| (x / sum) as f32))
                },
            );
            let g = gpu.get_pixel(x, y);
            match reference {
                None if g[3] == 0 => {}
                Some(c) if g[3] == 255 => {
                    compared += 1;
                    let err = (0..3)
                        .map(|k| (c[k] - g[k] as f64).abs())
                        .fold(0.0, f64::max);
                    total += err;
                    if err > PIXEL_TOLERANCE {
                        outliers += 1;
                    }
                }
                _ => coverage_mismatch += 1,
            }
        }
    }
    let mean = total / compared.max(1) as f64;
    let report = format!(
        "{compared} pixels compared, mean error {mean:.2}, {outliers} over {PIXEL_TOLERANCE}, \
         {coverage_mismatch} coverage mismatches"
    );
    // Coverage may differ only along the silhouette (about its perimeter in pixels).
    if compared < 1000
        || mean > MEAN_TOLERANCE
        || outliers as f64 > OUTLIER_FRACTION * compared as f64
        || coverage_mismatch as f64 > 0.02 * compared as f64
    {
        Err(report)
    } else {
        Ok(report)
    }
}

#[test]
fn lapped_render_matches_the_ray_cast() {
    let _serial = crate::serial();
    let Some(gpu) = crate::gpu() else { return };
    let model = model();
    if gpu.render_pipelines_crash() {
        // This process's llvmpipe runs 512 bits wide (the compute kernels' default on AVX-512
        // hosts), where compiling the render pipeline crashes it: the render refuses with a
        // clear error, and the comparison runs in a child process at 256 bits.
        let camera = Camera::orbit(&model, "30,20").unwrap();
        let refused = render(gpu, &model.render_scene(), &camera, 96)
            .unwrap_err()
            .to_string();
        assert!(refused.contains("LP_NATIVE_VECTOR_WIDTH=256"), "{refused}");
        // (The child must not refuse and spawn again.)
        assert!(
            std::env::var("LP_NATIVE_VECTOR_WIDTH").as_deref() != Ok("256"),
            "llvmpipe still runs 512 bits wide at LP_NATIVE_VECTOR_WIDTH=256: {}",
            gpu.describe()
        );
        let out = std::process::Command::new(std::env::current_exe().unwrap())
            .args([
                "lapped_render::lapped_render_matches_the_ray_cast",
                "--exact",
            ])
            .args(["--nocapture", "--test-threads=1"])
            .env("LP_NATIVE_VECTOR_WIDTH", "256")
            .output()
            .unwrap();
        let log = String::from_utf8_lossy(&out.stdout).into_owned()
            + &String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success() && log.contains("1 passed") && log.contains("256 bits"),
            "the render at 256 bits:\n{log}"
        );
        return;
    }
    for spec in ["30,20", "200,-35,3"] {
        let camera = Camera::orbit(&model, spec).unwrap();
        let image = render(gpu, &model.render_scene(), &camera, 96).unwrap();
        match compare(&model, &image, &camera) {
            Ok(report) => eprintln!("camera {spec}: {report}"),
            Err(report) => panic!("camera {spec}: {report}"),
        }
        // The comparison can fail: the same image against a camera moved by 10 degrees.
        let moved = Camera::orbit(
            &model,
            if spec == "30,20" {
                "40,20"
            } else {
                "210,-35,3"
            },
        )
        .unwrap();
        assert!(
            compare(&model, &image, &moved).is_err(),
            "camera {spec}: a moved camera passed"
        );
    }
}
