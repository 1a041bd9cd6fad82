//! Lapped solid textures: the `.lst` reader (round trip, seeded fuzz), cuts against direct
//! shading, the shipped example constraint files. The `solidsynth lapped` commands are checked
//! in tests/cli/lapped.rs, the GPU render in kernels-tests.

mod common;

use glam::DVec3;
use solidsynth::lapped::exemplar::SolidExemplar;
use solidsynth::lapped::field::Constraints;
use solidsynth::lapped::model::LstModel;
use solidsynth::lapped::{self, shapes, FillInputs, FillOptions};
use solidsynth::lazy::cut::CutSpec;
use solidsynth::util::hash::SeededRng;
use std::path::Path;

fn sphere_model(json: &str, resolution: u32) -> LstModel {
    let c = Constraints::parse(json.as_bytes(), "c.json").unwrap();
    let e = SolidExemplar::from_volume(&common::lapped_exemplar_volume(), "e").unwrap();
    let opts = FillOptions {
        resolution,
        ..Default::default()
    };
    let mesh = shapes::sphere(32, 16);
    lapped::build(
        FillInputs {
            mesh: &mesh,
            mesh_name: "sphere",
            exemplar: e,
            exemplar_source: "e",
            constraints: &c,
            constraints_name: "c.json",
        },
        &opts,
        &|_, _| {},
    )
    .unwrap()
    .0
}

// ---------------------------------------------------------------- model and format

#[test]
fn every_tet_is_covered_at_its_sample_points() {
    // Paper 5.2.6: the alpha of the layers, summed at each of a tet's 165 sample points, reaches
    // 255 (the fill rounds each layer's alpha to 8 bits: half a level each).
    let model = sphere_model(r#"{"type": "0"}"#, 6);
    let samples = solidsynth::lapped::tetmesh::coverage_samples();
    let mask = &model.masks[0];
    for t in 0..model.mesh.tets.len() {
        let layers = &model.layers[t];
        for b in &samples {
            let sum: f64 = layers
                .iter()
                .map(|l| {
                    let w = (0..4)
                        .map(|k| glam::Vec3::from_array(l.coords[k]).as_dvec3() * b[k])
                        .sum::<DVec3>();
                    mask.sample(w) as f64
                })
                .sum();
            let slack = 0.5 * layers.len() as f64 / 255.0 + 1e-4;
            assert!(sum >= 1.0 - slack, "tet {t} at {b:?}: alpha sum {sum}");
        }
    }
}

#[test]
fn lst_round_trips_and_rejects_damage() {
    let model = sphere_model(r#"{"type": "1-a", "strokes": [[[0,0,-0.5],[0,0,0.5]]]}"#, 5);
    let bytes = model.to_bytes();
    assert_eq!(LstModel::parse(&bytes).unwrap(), model);
    let mut flipped = bytes.clone();
    flipped[100] ^= 4;
    assert!(LstModel::parse(&flipped).unwrap_err().contains("checksum"));
    assert!(LstModel::parse(&bytes[..bytes.len() / 2])
        .unwrap_err()
        .contains("checksum"));
    assert!(LstModel::parse(b"not a model at all")
        .unwrap_err()
        .contains("magic"));
    let mut inverted = model.clone();
    inverted.mesh.tets[3].swap(0, 1);
    let e = LstModel::parse(&inverted.to_bytes()).unwrap_err();
    assert!(e.contains("tet 3 is flat or inverted"), "{e}");
}

/// Re-seal a mutated body with a valid CRC, so the mutation reaches the parser proper.
fn reseal(mut body: Vec<u8>) -> Vec<u8> {
    let crc = crc32fast::hash(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    body
}

/// Truncations, bit flips in the header and the counts, random bytes: errors, never panics.
#[test]
fn fuzz_lst_reader() {
    let good = sphere_model(r#"{"type": "0"}"#, 4).to_bytes();
    let body = good[..good.len() - 4].to_vec();
    let header_end = 12 + u32::from_le_bytes(body[8..12].try_into().unwrap()) as usize;
    let mut rng = SeededRng::new(77);
    let (mut rejected, mut accepted) = (0, 0);
    for i in 0..3000 {
        let mut b = body.clone();
        match i % 4 {
            0 => b.truncate(rng.below(b.len() as u64) as usize),
            1 => {
                let at = rng.below(header_end as u64 + 64) as usize;
                b[at] ^= 1 << rng.below(8);
            }
            2 => {
                let at = rng.below(b.len() as u64) as usize;
                b[at] = rng.below(256) as u8;
            }
            _ => {
                let at = 8 + rng.below(header_end as u64) as usize;
                b.insert(at, b"9 \"-{}"[rng.below(6) as usize]);
            }
        }
        let sealed = reseal(b);
        match std::panic::catch_unwind(|| LstModel::parse(&sealed)) {
            Ok(Ok(m)) => {
                accepted += 1;
                assert_eq!(m.layers.len(), m.mesh.tets.len());
            }
            Ok(Err(_)) => rejected += 1,
            Err(_) => panic!("reader panicked on mutation {i}"),
        }
    }
    assert!(
        rejected > 500 && accepted > 100,
        "rejected {rejected}, accepted {accepted}"
    );
}

#[test]
fn cut_pixels_equal_direct_shading_of_their_points() {
    let model = sphere_model(
        r#"{"type": "2-b", "strokes": [[[0.6,0,-0.3],[0.6,0,0.3]]], "depth": {"inner": [[[0,0,-0.5],[0,0,0.5]]]}}"#,
        6,
    );
    let spec = CutSpec {
        origin: [0.05, -0.1, 0.2],
        normal: [0.3, 0.5, 1.0],
        up: None,
        size: 48,
        spacing: 2.4 / 48.0,
    };
    let img = lapped::cut::cut(&model, &spec).unwrap();
    let (u, v, _) = spec.frame().unwrap();
    let o = DVec3::from_array(spec.origin);
    let (mut inside, mut checked) = (0, 0);
    for j in 0..spec.size {
        for i in 0..spec.size {
            let p = o
                + (i as f64 + 0.5 - 24.0) * spec.spacing * u
                + (j as f64 + 0.5 - 24.0) * spec.spacing * v;
            let pixel = img.get_pixel(i, j);
            // The tet holding p, if any, with a margin so edge pixels are not ambiguous.
            let bary = |t: usize| model.mesh.barycentric(t, p);
            let tets = 0..model.mesh.tets.len();
            let holder = tets.clone().find(|&t| bary(t).iter().all(|&b| b >= 1e-4));
            let near = tets.clone().any(|t| bary(t).iter().all(|&b| b >= -1e-4));
            let Some(t) = holder else {
                if !near {
                    assert_eq!(pixel[3], 0, "pixel {i},{j} off the model");
                }
                continue;
            };
            inside += 1;
            assert_eq!(pixel[3], 255, "pixel {i},{j}");
            let want = model.shade(t, bary(t).map(|x| x as f32));
            for c in 0..3 {
                let diff = (pixel[c] as f32 - want[c].round()).abs();
                assert!(
                    diff <= 1.0,
                    "pixel {i},{j} channel {c}: {} vs {}",
                    pixel[c],
                    want[c]
                );
            }
            checked += 1;
        }
    }
    assert!(
        inside > 500 && checked > 500,
        "{inside} inside, {checked} checked"
    );
}

#[test]
fn example_constraint_files_parse_and_fill_their_shapes() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/lapped");
    let names = [
        "kiwi.json",
        "bent-cylinder.json",
        "bunny.json",
        "onion.json",
        "fibres.json",
        "strata.json",
    ];
    for name in names {
        Constraints::load(&dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    let e = SolidExemplar::from_volume(&common::lapped_exemplar_volume(), "e").unwrap();
    let opts = FillOptions {
        resolution: 6,
        ..Default::default()
    };
    for (name, mesh) in [
        ("kiwi.json", shapes::sphere(32, 16)),
        (
            "bent-cylinder.json",
            shapes::bent_cylinder(0.3, 1.0, 24, 24),
        ),
        ("onion.json", shapes::sphere(32, 16)),
        ("fibres.json", shapes::bent_cylinder(0.3, 1.0, 24, 24)),
        ("strata.json", shapes::sphere(32, 16)),
    ] {
        let c = Constraints::load(&dir.join(name)).unwrap();
        let (model, report) = lapped::build(
            FillInputs {
                mesh: &mesh,
                mesh_name: name,
                exemplar: e.clone(),
                exemplar_source: "e",
                constraints: &c,
                constraints_name: name,
            },
            &opts,
            &|_, _| {},
        )
        .unwrap();
        assert_eq!(report.quality.inverted, 0, "{name}");
        assert!(model.layers.iter().all(|l| !l.is_empty()), "{name}");
    }
}

#[test]
fn field_axes_follow_the_constraints() {
    // 1-a along z: every interior tet's s axis is close to +-z.
    use solidsynth::lapped::field::Field;
    let (mesh, _) = solidsynth::lapped::stuffing::stuff(&shapes::sphere(32, 16), 6, "s").unwrap();
    let c = Constraints::parse(
        br#"{"type": "1-a", "strokes": [[[0,0,-0.6],[0,0,0.6]]]}"#,
        "c",
    )
    .unwrap();
    let field = Field::compute(&mesh, &c, 0.5).unwrap();
    for t in 0..mesh.tets.len() {
        let f = field.tet_frame(&mesh, t);
        assert!(f.s.normalize().z.abs() > 0.99, "tet {t}: {:?}", f.s);
        assert!((f.s.length() - 0.5).abs() < 1e-9);
    }
    // 2-b: the primary axis points inward (towards the z axis), scale from |grad depth|.
    let c = Constraints::parse(
        br#"{"type": "2-b", "strokes": [[[0.6,0,-0.3],[0.6,0,0.3]]], "depth": {"inner": [[[0,0,-0.6],[0,0,0.6]]]}}"#,
        "c",
    )
    .unwrap();
    let field = Field::compute(&mesh, &c, 0.5).unwrap();
    let depth = field.depth.as_ref().unwrap();
    let mut agree = 0;
    for t in 0..mesh.tets.len() {
        let p = mesh.centroid(t);
        let radial = DVec3::new(-p.x, -p.y, 0.0);
        if radial.length() < 0.4 {
            continue;
        }
        let f = field.tet_frame(&mesh, t);
        if f.s.normalize().dot(radial.normalize()) > 0.8 {
            agree += 1;
        }
        // Secondary (r) is orthogonal to the primary.
        assert!(f.r.normalize().dot(f.s.normalize()).abs() < 1e-9);
    }
    assert!(agree > 0);
    // Depth: 0 on the surface, ~1 on the axis.
    let surface_max = mesh
        .vertices
        .iter()
        .zip(depth)
        .filter(|(p, _)| p.length() > 0.99)
        .map(|(_, d)| *d)
        .fold(0.0, f64::max);
    assert!(surface_max < 0.05, "surface depth {surface_max}");
}
