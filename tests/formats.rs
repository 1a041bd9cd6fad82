//! Volume formats chosen by `-o`'s extension, each read back by an independent reader and
//! compared with the NRRD of the same command: NumPy for `.npy`, tifffile for TIFF stacks (both
//! Python: `$SOLIDSYNTH_TEST_PYTHON`, else `python3`; `.ci/run` makes a virtual environment with
//! them), the `ktx2` crate for KTX2. Bad outputs are refused by name.

use std::path::Path;
use std::process::Command;

fn solidsynth(command_line: &str, dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_solidsynth"))
        .args(command_line.split_whitespace())
        .current_dir(dir)
        .env("SOLIDSYNTH_CACHE_DIR", dir.join("cache"))
        .output()
        .unwrap()
}

fn ok(command_line: &str, dir: &Path) {
    let out = solidsynth(command_line, dir);
    assert!(
        out.status.success(),
        "{command_line}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Run a Python script that prints what it read (the readers are NumPy and tifffile).
fn python(script: &str, dir: &Path) -> String {
    let python = std::env::var_os("SOLIDSYNTH_TEST_PYTHON").unwrap_or_else(|| "python3".into());
    let out = Command::new(&python)
        .arg("-c")
        .arg(script)
        .current_dir(dir)
        .output()
        .expect("Python runs (see .ci/run: a virtual environment with numpy and tifffile)");
    assert!(
        out.status.success(),
        "python failed:\n{script}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

/// The NRRD data of `name` (as the library reads it).
fn nrrd_data(dir: &Path, name: &str) -> solidsynth::Volume {
    solidsynth::io::nrrd::load(&dir.join(name)).unwrap()
}

#[test]
fn npy_and_tiff_stacks_hold_the_nrrd_voxels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = "region --box=-5,3,7,19,15,16 --seed 4 --backend cpu";
    ok(&format!("{common} -o v.nrrd"), d);
    ok(&format!("{common} -o v.npy"), d);
    ok(&format!("{common} -o v.tif"), d);
    ok(&format!("{common} -o v.data --format npy"), d);
    let v = nrrd_data(d, "v.nrrd");
    assert_eq!((v.nx, v.ny, v.nz, v.channels), (24, 12, 9, 3));
    std::fs::write(d.join("expected.raw"), &v.data).unwrap();
    let report = python(
        "import numpy as np\n\
         a = np.load('v.npy')\n\
         b = np.load('v.data')\n\
         raw = open('expected.raw', 'rb').read()\n\
         print(a.dtype, a.shape, a.tobytes() == raw, np.array_equal(a, b))",
        d,
    );
    assert_eq!(report, "uint8 (9, 12, 24, 3) True True");
    let report = python(
        "import tifffile\n\
         with tifffile.TiffFile('v.tif') as t:\n\
         \x20   a = t.asarray()\n\
         \x20   print(len(t.pages), t.is_imagej, t.imagej_metadata.get('slices'))\n\
         raw = open('expected.raw', 'rb').read()\n\
         print(a.dtype, a.shape, a.tobytes() == raw)",
        d,
    );
    assert_eq!(report, "9 True 9\nuint8 (9, 12, 24, 3) True");
}

#[test]
fn gzip_nrrd_holds_the_raw_nrrd_voxels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = "region --box=-5,3,7,19,15,16 --seed 4 --backend cpu";
    ok(&format!("{common} -o v.nrrd"), d);
    ok(&format!("{common} -o z.nrrd --format nrrd-gzip"), d);
    // Small groups: the data arrives in several slabs, each compressed as it comes.
    ok(
        &format!("{common} -o s.nrrd --format nrrd-gzip --max-group 8"),
        d,
    );
    let v = nrrd_data(d, "v.nrrd");
    assert_eq!(nrrd_data(d, "z.nrrd"), v);
    assert_eq!(nrrd_data(d, "s.nrrd"), v);
    std::fs::write(d.join("expected.raw"), &v.data).unwrap();
    // An independent reader: Python's own gzip after the header's blank line.
    let report = python(
        "import gzip\n\
         b = open('z.nrrd', 'rb').read()\n\
         header, data = b.split(b'\\n\\n', 1)\n\
         print(b'encoding: gzip' in header.split(b'\\n'), \
         gzip.decompress(data) == open('expected.raw', 'rb').read())",
        d,
    );
    assert_eq!(report, "True True");
    assert!(std::fs::metadata(d.join("z.nrrd")).unwrap().len() < v.data.len() as u64);
}

#[test]
fn ktx2_textures_read_back_with_their_levels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = "synth --size 16 --seed 2 --backend cpu";
    ok(&format!("{common} -o v.nrrd"), d);
    ok(&format!("{common} -o v.ktx2"), d);
    ok(&format!("{common} -o m.ktx2 --mips --srgb"), d);
    let v = nrrd_data(d, "v.nrrd");
    let rgba: Vec<u8> = v
        .data
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    let bytes = std::fs::read(d.join("v.ktx2")).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).expect("a valid KTX2 file");
    let header = reader.header();
    assert_eq!(header.format, Some(ktx2::Format::R8G8B8A8_UNORM));
    assert_eq!(
        (header.pixel_width, header.pixel_height, header.pixel_depth),
        (16, 16, 16)
    );
    assert_eq!(header.level_count, 1);
    let levels: Vec<_> = reader.levels().collect();
    assert_eq!(levels[0].data, &rgba[..]);

    let bytes = std::fs::read(d.join("m.ktx2")).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).expect("a valid KTX2 file");
    assert_eq!(reader.header().format, Some(ktx2::Format::R8G8B8A8_SRGB));
    let levels: Vec<_> = reader.levels().collect();
    assert_eq!(levels.len(), 5, "16, 8, 4, 2, 1");
    assert_eq!(levels[0].data, &rgba[..]);
    assert_eq!(levels[4].data.len(), 4);
}

#[test]
fn unknown_extensions_and_misplaced_options_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (command_line, output, needle) in [
        (
            "synth --size 16 --backend cpu -o v.exr",
            "v.exr",
            ".nrrd, .npy",
        ),
        (
            "synth --size 16 --backend cpu -o volume",
            "volume",
            "no extension",
        ),
        (
            "synth --size 16 --backend cpu -o v.nrrd --mips",
            "v.nrrd",
            "only KTX2",
        ),
        (
            "gradient render missing.gsolid -o g.exr",
            "g.exr",
            "cannot be written as .exr",
        ),
    ] {
        let out = solidsynth(command_line, d);
        assert_eq!(out.status.code(), Some(2), "{command_line}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{command_line}: {err}");
        assert!(!d.join(output).exists(), "{command_line} wrote {output}");
    }
}

#[test]
fn a_surface_summary_names_where_the_mesh_lies_in_the_solid() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/octahedron.obj");
    let out = solidsynth(
        &format!("surface --mesh {mesh} --resolution 16 --texels 4 --backend cpu -o o.glb --json"),
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let placement = &summary["placement"];
    assert_eq!(
        placement["voxel_box"],
        serde_json::json!([[0, 0, 0], [16, 16, 16]])
    );
    assert_eq!(placement["origin"], serde_json::json!([-1.0, -1.0, -1.0]));
    assert!((placement["scale"].as_f64().unwrap() - 8.0).abs() < 1e-5);
    // The .glb carries a unit NORMAL per corner.
    let glb = std::fs::read(d.join("o.glb")).unwrap();
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let attributes = &doc["meshes"][0]["primitives"][0]["attributes"];
    let normal = attributes["NORMAL"].as_u64().expect("a NORMAL attribute") as usize;
    let accessor = &doc["accessors"][normal];
    let view = &doc["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
    let start = 28 + json_len + view["byteOffset"].as_u64().unwrap() as usize;
    let floats: Vec<f32> = glb[start..start + view["byteLength"].as_u64().unwrap() as usize]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(floats.len(), 8 * 3 * 3);
    for n in floats.chunks_exact(3) {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5, "{n:?}");
    }
}

#[test]
fn a_ktx2_texture_loads_into_a_wgpu_3d_texture_unchanged() {
    use solidsynth::gpu::{GpuContext, GpuOptions};
    let gpu = match GpuContext::new(&GpuOptions::from_env()) {
        Ok(gpu) => gpu,
        Err(e) if std::env::var_os("CI").is_some() => panic!("CI is set but no GPU: {e}"),
        Err(e) => return eprintln!("SKIPPED (no GPU adapter, CI unset): {e}"),
    };
    // 64 texels wide: a row of RGBA8 is 256 bytes, wgpu's copy alignment.
    let mut v = solidsynth::Volume::new(64, 8, 4, 3);
    v.data
        .iter_mut()
        .enumerate()
        .for_each(|(i, b)| *b = (i * 7 % 251) as u8);
    let bytes = solidsynth::io::ktx2::to_bytes(&v, Default::default()).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).unwrap();
    let header = reader.header();
    assert_eq!(header.format, Some(ktx2::Format::R8G8B8A8_UNORM));
    let level = reader.levels().next().unwrap().data.to_vec();
    let extent = wgpu::Extent3d {
        width: header.pixel_width,
        height: header.pixel_height,
        depth_or_array_layers: header.pixel_depth,
    };
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("ktx2 volume"),
        size: extent,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let layout = wgpu::TexelCopyBufferLayout {
        offset: 0,
        bytes_per_row: Some(extent.width * 4),
        rows_per_image: Some(extent.height),
    };
    let copy = wgpu::TexelCopyTextureInfo {
        texture: &texture,
        mip_level: 0,
        origin: wgpu::Origin3d::ZERO,
        aspect: wgpu::TextureAspect::All,
    };
    gpu.queue.write_texture(copy, &level, layout, extent);
    let readback = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("ktx2 readback"),
        size: level.len() as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    encoder.copy_texture_to_buffer(
        copy,
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout,
        },
        extent,
    );
    gpu.submit_and_wait(encoder).unwrap();
    let words = gpu.read_words(&readback, level.len() / 4).unwrap();
    let back: &[u8] = bytemuck::cast_slice(&words);
    let rgba: Vec<u8> = v
        .data
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    assert_eq!(back, &rgba[..]);
}

#[test]
fn openvdb_files_read_back_with_openvdb() {
    // OpenVDB's own reader (Debian's python3-openvdb, for the system Python; `.ci/run` installs
    // it): grid names, classes, bounding boxes, voxel size and origin, and every voxel.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = "region --box=-5,3,7,19,15,16 --seed 4 --backend cpu";
    ok(&format!("{common} -o v.nrrd"), d);
    ok(&format!("{common} -o v.vdb"), d);
    ok(&format!("{common} --voxel-size 0.5 -o half.vdb"), d);
    std::fs::write(d.join("v.raw"), &nrrd_data(d, "v.nrrd").data).unwrap();
    let python =
        std::env::var_os("SOLIDSYNTH_TEST_VDB_PYTHON").unwrap_or_else(|| "/usr/bin/python3".into());
    let check = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/vdb_check.py");
    for (file, placement) in [
        ("v.vdb", "--origin -5 3 7"),
        ("half.vdb", "--voxel-size 0.5 --origin -2.5 1.5 3.5"),
    ] {
        let out = Command::new(&python)
            .arg(check)
            .args([file, "v.raw", "24", "12", "9", "3", "--quiet"])
            .args(placement.split_whitespace())
            .current_dir(d)
            .output()
            .expect("the system Python runs (python3-openvdb: see .ci/run)");
        let report = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && report.trim().ends_with("ok"),
            "{file}: {report}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // The options belong to their formats.
    let out = solidsynth(&format!("{common} --voxel-size 0.5 -o v2.nrrd"), d);
    assert_eq!(out.status.code(), Some(2));
    assert!(!d.join("v2.nrrd").exists());
}

/// The glTF JSON chunk of a .glb.
fn glb_json(glb: &[u8]) -> serde_json::Value {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&glb[20..20 + json_len]).unwrap()
}

#[test]
fn surfaces_bake_into_the_meshs_own_uvs_and_pad_cells_for_mips() {
    use solidsynth::mesh::{bake::Atlas, Placement};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = env!("CARGO_MANIFEST_DIR");
    let exemplar = format!("{root}/tests/fixtures/cells32.png --periodic");
    let cube = format!("{root}/examples/uv-cube.obj");
    let solid = format!("{exemplar} --seed 3 --backend cpu");
    ok(&format!("region {solid} --box 0,0,0,16,16,16 -o r.nrrd"), d);
    let volume = nrrd_data(d, "r.nrrd");
    ok(
        &format!(
            "surface {solid} --mesh {cube} --resolution 16 --uv own --texture-size 64 -o own.obj"
        ),
        d,
    );
    // Every texel a triangle covers is the solid at its point; every texel next to them (the
    // first ring of the dilation) is the rounded mean of its covered neighbours.
    let mesh = solidsynth::mesh::load(Path::new(&cube)).unwrap();
    assert_eq!(mesh.uvs.as_ref().map(Vec::len), Some(12));
    let place = Placement::fit(&mesh, 16);
    let atlas = Atlas::mesh_uvs(&mesh, &place, Some(64), "cube", |_| true).unwrap();
    let img = image::open(d.join("own.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (64, 64));
    let owners: Vec<u32> = atlas.texel_points(&mesh).iter().map(|p| p.0).collect();
    let voxels = atlas.texel_voxels(&mesh, &place);
    let covered = |x: i64, y: i64| {
        (0..64).contains(&x) && (0..64).contains(&y) && owners[(y * 64 + x) as usize] != u32::MAX
    };
    let (mut inside, mut ring) = (0, 0);
    for y in 0..64i64 {
        for x in 0..64i64 {
            let got = img.get_pixel(x as u32, y as u32).0;
            if covered(x, y) {
                let p = voxels[(y * 64 + x) as usize];
                assert_eq!(
                    &got[..],
                    volume.at(p[0] as u32, p[1] as u32, p[2] as u32),
                    "texel {x},{y}"
                );
                inside += 1;
                continue;
            }
            let near: Vec<[u8; 3]> = (-1..=1)
                .flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy)))
                .filter(|&(nx, ny)| covered(nx, ny))
                .map(|(nx, ny)| img.get_pixel(nx as u32, ny as u32).0)
                .collect();
            if !near.is_empty() {
                let n = near.len() as u32;
                let mean: Vec<u8> = (0..3)
                    .map(|c| ((near.iter().map(|p| p[c] as u32).sum::<u32>() + n / 2) / n) as u8)
                    .collect();
                assert_eq!(&got[..], &mean[..], "ring texel {x},{y}");
                ring += 1;
            }
        }
    }
    // Six faces of 64/3 - 2 by 32 - 2 texels, and the ring around each.
    assert!(
        inside > 6 * 18 * 28 && ring > 6 * 2 * (18 + 28),
        "{inside} {ring}"
    );

    // The .glb shares the vertices of each face (24 corners for 36 triangle corners), carries
    // normals and samples through mipmaps.
    ok(
        &format!("surface {solid} --mesh {cube} --resolution 16 --uv own -o own.glb --json"),
        d,
    );
    let doc = glb_json(&std::fs::read(d.join("own.glb")).unwrap());
    let primitive = &doc["meshes"][0]["primitives"][0];
    let count = |name: &str| {
        doc["accessors"][primitive["attributes"][name].as_u64().unwrap() as usize]["count"].clone()
    };
    assert_eq!(count("POSITION"), 24);
    assert_eq!(count("NORMAL"), 24);
    assert_eq!(
        doc["accessors"][primitive["indices"].as_u64().unwrap() as usize]["count"],
        36
    );
    assert_eq!(doc["samplers"][0]["minFilter"], 9987);

    // --mips K: every packed cell gets a gutter of 2^K texels; the cells still hold the solid.
    let out = solidsynth(
        &format!("surface {solid} --mesh {cube} --resolution 16 --mips 2 -o mips.obj --json"),
        d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["gutter"], 4);
    assert_eq!(summary["mip_safe"], true);
    let padded = Atlas::fitted(&mesh, &place, 1.0, 4).unwrap();
    let plain = Atlas::fitted(&mesh, &place, 1.0, 0).unwrap();
    assert_eq!(
        summary["atlas"],
        serde_json::json!([padded.width, padded.height])
    );
    assert!(padded.texel_count() > plain.texel_count());
    let img = image::open(d.join("mips.png")).unwrap().to_rgb8();
    let voxels = padded.texel_voxels(&mesh, &place);
    for cell in padded.cells() {
        assert!(cell.x >= 4 && cell.y >= 4);
        for y in cell.y..cell.y + cell.height {
            for x in cell.x..cell.x + cell.width {
                let p = voxels[(y * padded.width + x) as usize];
                let want = volume.at(p[0] as u32, p[1] as u32, p[2] as u32);
                assert_eq!(&img.get_pixel(x, y).0[..], want, "cell texel {x},{y}");
            }
        }
        // The gutter's corner, four rings out along the diagonal, has one filled neighbour in
        // each ring before it: it repeats the cell's corner texel.
        let corner = img.get_pixel(cell.x - 4, cell.y - 4).0;
        assert_eq!(
            corner,
            img.get_pixel(cell.x, cell.y).0,
            "gutter corner of {cell:?}"
        );
    }
}

#[test]
fn own_uvs_that_are_missing_overlap_or_meet_packed_flags_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = env!("CARGO_MANIFEST_DIR");
    let solid = format!("{root}/tests/fixtures/cells32.png --periodic --backend cpu");
    // Two triangles mapped onto the same texels.
    std::fs::write(
        d.join("stacked.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0.1 0.1\nvt 0.9 0.1\nvt 0.1 0.9\n\
         f 1/1 2/2 3/3\nf 2/1 4/2 3/3\n",
    )
    .unwrap();
    let cases = [
        (
            format!("--mesh {root}/examples/octahedron.obj --uv own"),
            "octahedron.obj: the mesh has no texture coordinates",
        ),
        (
            "--mesh stacked.obj --uv own".to_string(),
            "triangle 0 and triangle 1 both cover texel",
        ),
        (
            format!("--mesh {root}/examples/uv-cube.obj --uv own --mips 2"),
            "--uv own",
        ),
        (
            format!("--mesh {root}/examples/uv-cube.obj --texture-size 64"),
            "--texture-size",
        ),
        (
            format!("--mesh {root}/examples/uv-cube.obj --uv own --texture-size 0"),
            "--texture-size 0",
        ),
    ];
    for (flags, needle) in cases {
        let out = solidsynth(
            &format!("surface {solid} {flags} --resolution 16 -o bad.glb"),
            d,
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flags}: {stderr}");
        assert!(
            stderr.contains(needle),
            "{flags}: expected '{needle}' in {stderr}"
        );
        assert!(!d.join("bad.glb").exists(), "{flags}");
    }
}
