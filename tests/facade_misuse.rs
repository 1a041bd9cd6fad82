//! What an application can get wrong through the library's public types (hand-built images,
//! volumes, captures and plans; values past the engine's ranges) is refused with an error that
//! names it, never a panic.

mod common;

use solidsynth::exemplar::Image;
use solidsynth::synth::{ChannelSource, ChannelSources, ColorSource};
use solidsynth::volume::Volume;
use solidsynth::{Box3, Compute, Solid};

fn refused<T>(r: solidsynth::Result<T>, needle: &str) {
    let Err(e) = r else {
        panic!("not refused: expected an error with '{needle}'")
    };
    assert!(e.is_user_error(), "{e}");
    assert!(e.to_string().contains(needle), "'{needle}' not in: {e}");
}

fn marble_solid() -> Solid {
    Solid::builder()
        .exemplar(common::fixture("marble32.png"))
        .balance(0, 1.0)
        .cpu()
        .build()
        .unwrap()
}

#[test]
fn hand_built_inputs_that_disagree_with_their_sizes_are_refused() {
    let image = |channels, pixels| Image {
        width: 32,
        height: 32,
        channels,
        pixels,
    };
    let build = |img: Image| Solid::builder().exemplar(img).cpu().build();
    refused(build(image(0, vec![])), "image has 0 channels");
    refused(build(image(2, vec![0; 2048])), "image has 2 channels");
    refused(
        build(image(3, vec![0; 100])),
        "holds 100 bytes; 32x32 pixels of 3 channels take 3072",
    );
    let gradient = solidsynth::gradient::synth::synthesize(
        &Image::new(0, 0, 3),
        &Default::default(),
        &Compute::Cpu,
        &|_, _| {},
    );
    refused(gradient, "exemplar is 0x0");

    let marble = common::fixture("marble32.png");
    let volume = Volume::new(16, 16, 16, 3);
    let params = solidsynth::metrics::EvalParams::default();
    refused(
        solidsynth::metrics::evaluate(&volume, &[], &params),
        "0 images",
    );
    refused(
        solidsynth::metrics::evaluate(&volume, &[marble.clone(), marble.clone()], &params),
        "2 images",
    );
    let short = Volume {
        data: vec![0; 10],
        ..volume.clone()
    };
    refused(
        solidsynth::metrics::evaluate(&short, std::slice::from_ref(&marble), &params),
        "holds 10 bytes",
    );
    // Sizes whose byte count passes 2^64 (it wrapped to 0, so empty data passed).
    let vast = Volume {
        nx: 1 << 22,
        ny: 1 << 22,
        nz: 1 << 22,
        channels: 4,
        data: vec![],
    };
    refused(
        solidsynth::metrics::evaluate(&vast, &[marble], &params),
        "take more than 2^64",
    );

    // A volume writer refuses a slab whose data is short, and a file left incomplete.
    let dir = tempfile::tempdir().unwrap();
    refused(
        solidsynth::io::nrrd::save(&short, &dir.path().join("short.nrrd")),
        "holds 10 bytes",
    );
    assert!(!dir.path().join("short.nrrd").exists());
    let mut writer =
        solidsynth::io::nrrd::SlabWriter::create(&dir.path().join("part.nrrd"), [16; 3], 3)
            .unwrap();
    writer.write_slab(&Volume::new(16, 16, 4, 3)).unwrap();
    refused(
        writer.write_slab(&Volume::new(8, 16, 4, 3)),
        "does not continue",
    );
    refused(writer.finish(), "4 of its 16 z slices");
    assert!(!dir.path().join("part.nrrd").exists());

    // A capture built in memory without names still has its image sizes checked.
    let mut capture = solidsynth::ptm::capture::synthetic(32, 8, 1);
    capture.names.clear();
    capture.images[7] = image::RgbImage::new(4, 4);
    refused(
        solidsynth::ptm::fit::fit(&capture, solidsynth::ptm::PtmFormat::Rgb, "capture"),
        "image 7",
    );
}

#[test]
fn values_past_the_engines_ranges_are_refused() {
    let five = ColorSource::PerChannel(ChannelSources {
        sources: [ChannelSource::X; 4],
        len: 5,
    });
    refused(
        Solid::builder().color(five).cpu().build(),
        "5 channel sources",
    );
    refused(
        Solid::builder().max_group(Some(3)).cpu().build(),
        "--max-group 3",
    );
    refused(
        Solid::builder().max_group(Some(6)).cpu().build(),
        "--max-group 6: must be a multiple of 4",
    );
    let mut solid = marble_solid();
    refused(solid.sample(&[[i32::MAX, 0, 0]]), "lies beyond");
    let huge = Box3::new([-(1 << 28); 3], [1 << 28; 3]);
    refused(solid.region(huge), "of memory");
    let mut buffer = [0u8; 4];
    refused(solid.region_into(huge, &mut buffer), "holds 4 bytes");
    refused(solid.tileable(1 << 21), "of memory");
    // Two voxels at opposite corners of the coordinate range: two bricks, whose bounding box
    // holds more voxels than a u64 counts.
    let far = [[-(1 << 28); 3], [1 << 28; 3]];
    let colors = solid.sample(&far).unwrap();
    assert_eq!(colors[0], solid.sample(&far[..1]).unwrap()[0]);
}

#[test]
fn a_surface_plan_bakes_only_its_own_mesh() {
    use solidsynth::solid::surface::{AtlasLayout, SurfacePlan};
    let tri = solidsynth::mesh::parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "a").unwrap();
    let quad = solidsynth::mesh::parse_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", "b")
        .unwrap();
    let layout = AtlasLayout::Texels {
        texels: 8,
        gutter: 0,
    };
    refused(
        SurfacePlan::new(&tri, "a", 0, layout, None, 128),
        "--resolution 0",
    );
    let plan = SurfacePlan::new(&tri, "a", 32, layout, None, 128).unwrap();
    let mut solid = marble_solid();
    refused(
        solid.bake_surface(&quad, &plan),
        "not the mesh its surface plan",
    );
    let mut moved = tri.clone();
    moved.positions[0][0] = -5.0;
    refused(
        solid.bake_surface(&moved, &plan),
        "not the mesh its surface plan",
    );
    assert!(solid.bake_surface(&tri, &plan).is_ok());
    assert_eq!(AtlasLayout::gutter_for_mips(40), u32::MAX);
}

#[test]
fn a_solid_works_again_after_a_cancellation_with_a_new_token() {
    let token = solidsynth::util::cancel::CancelToken::new();
    let mut solid = Solid::builder()
        .exemplar(common::fixture("marble32.png"))
        .balance(0, 1.0)
        .cancel(token.clone())
        .cpu()
        .build()
        .unwrap();
    let b = Box3::new([0; 3], [8; 3]);
    token.cancel();
    assert!(matches!(solid.region(b), Err(solidsynth::Error::Cancelled)));
    solid.set_cancel(Some(solidsynth::util::cancel::CancelToken::new()));
    assert_eq!(solid.region(b).unwrap(), marble_solid().region(b).unwrap());
    // Debug output for an application's own structs.
    assert!(format!("{solid:?}").contains("Solid"));
    assert!(format!("{:?}", solid.into_cut_session()).contains("CutSession"));
}

#[test]
fn the_other_domains_refuse_hand_built_values() {
    use solidsynth::io::volume_file::{self, VolumeFormat, VolumeOutput, VolumeWriter};
    let dir = tempfile::tempdir().unwrap();
    // Every volume format refuses a volume no format holds, and a slab that does not continue.
    let ktx2 = dir.path().join("v.ktx2");
    let output = VolumeOutput::resolve(&ktx2, "-o", None, Default::default()).unwrap();
    refused(
        volume_file::save(&Volume::new(0, 4, 4, 1), &ktx2, output),
        "sides of at least one voxel",
    );
    let vti = dir.path().join("v.vti");
    let output =
        VolumeOutput::resolve(&vti, "-o", Some(VolumeFormat::Vti), Default::default()).unwrap();
    let mut writer = VolumeWriter::create(&vti, output, [4, 4, 8], 3).unwrap();
    refused(
        writer.write_slab(&Volume::new(8, 8, 1, 1)),
        "does not continue",
    );
    writer.write_slab(&Volume::new(4, 4, 2, 3)).unwrap();
    refused(writer.finish(), "2 of its 8 z slices");
    assert!(!vti.exists() && !ktx2.exists());

    // Gradient solids and their edits.
    use solidsynth::gradient::{edit, GradientSolid, Query};
    let mut solid = GradientSolid::new([3, 3, 3], 3).unwrap();
    refused(
        edit::edit(&mut solid, &[], &[255.0, 0.0, 0.0], Default::default()),
        "no strokes",
    );
    let hollow = GradientSolid {
        data: vec![],
        ..solid.clone()
    };
    refused(
        Compute::Cpu.tricubic_eval(&hollow, &Query::volume([4, 4, 4])),
        "holds 0 values",
    );

    // PTMs: texels that disagree with the sizes, a quilt overlap past any block.
    use solidsynth::ptm::{Lighting, Ptm, PtmFormat};
    let empty = Ptm {
        format: PtmFormat::Rgb,
        width: 4,
        height: 4,
        scale: [1.0; 6],
        bias: [0; 6],
        texels: vec![],
    };
    let light = Lighting {
        lu: 0.0,
        lv: 0.0,
        specular: 0.0,
    };
    refused(
        Compute::Cpu.ptm_relight(&empty, &light),
        "holds 0 bytes of texels",
    );
    refused(
        solidsynth::ptm::format::save(&dir.path().join("e.ptm"), &empty),
        "holds 0 bytes of texels",
    );
    use solidsynth::ptm::capture;
    let source =
        solidsynth::ptm::fit::fit(&capture::synthetic(32, 8, 1), PtmFormat::Rgb, "c").unwrap();
    let quilt = solidsynth::ptm::quilt::QuiltParams {
        overlap: 1 << 31,
        ..solidsynth::ptm::quilt::QuiltParams::new(64)
    };
    refused(quilt.validate(&source), "--overlap 2147483648");

    // Captures: saved without names (then named by place) and read back; a horizon light
    // renders (its shadow march is bounded).
    let mut unnamed = capture::synthetic(16, 8, 1);
    unnamed.names.clear();
    capture::save(&unnamed, &dir.path().join("cap")).unwrap();
    assert_eq!(
        capture::load(&dir.path().join("cap"), None).unwrap().images,
        unnamed.images
    );
    let horizon = capture::Light { lu: 1.0, lv: 0.0 };
    assert_eq!(
        capture::render(&capture::surface(16, 1), horizon).dimensions(),
        (16, 16)
    );

    // Frames of no images.
    refused(
        solidsynth::analysis::frame::resolve_frame(&[], None),
        "0 images",
    );
}

#[test]
fn meshes_atlases_and_writers_refuse_what_does_not_fit() {
    use solidsynth::mesh::{bake, glb, Mesh, Placement};
    let triangle = Mesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        triangles: vec![[0, 1, 2]],
        uvs: None,
        normals: None,
    };
    let beyond = Mesh {
        triangles: vec![[0, 1, 7]],
        ..triangle.clone()
    };
    // The parsers return only meshes that validate (they used to leave that to `mesh::load`).
    let ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
        property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
    refused(
        solidsynth::mesh::parse_ply(ply, "t.ply"),
        "beyond the 3 defined",
    );

    // An atlas belongs to its mesh: the writers refuse another before writing anything.
    let place = Placement::fit(&triangle, 16);
    assert!(bake::Atlas::fitted(&beyond, &place, 1.0, 0).is_none());
    refused(
        bake::Atlas::fitted_within(&beyond, &place, Some(1.0), 0, |_| true),
        "beyond the 3 defined",
    );
    let two = bake::Atlas::new(2, 4, 0).unwrap();
    refused(
        glb::glb_bytes(&triangle, &two, &[0; 8]),
        "made for 2 triangles",
    );
    refused(
        glb::glb_bytes(&beyond, &two, &[0; 8]),
        "beyond the 3 defined",
    );
    refused(
        bake::obj_text(&triangle, &two, "m.mtl"),
        "made for 2 triangles",
    );
    let mut out = Vec::new();
    let e = glb::write_glb(&mut out, &triangle, &two, &[0; 8]).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
    assert!(out.is_empty());
    let one = bake::Atlas::new(1, 4, 0).unwrap();
    assert!(glb::glb_bytes(&triangle, &one, &[0; 8]).is_ok());

    // The in-memory volume writers check what the file writers check.
    let short = Volume {
        data: vec![0; 10],
        ..Volume::new(4, 4, 4, 3)
    };
    refused(
        solidsynth::io::ktx2::to_bytes(&short, Default::default()),
        "holds 10 bytes",
    );
    refused(solidsynth::io::vti::to_bytes(&short), "holds 10 bytes");
    refused(
        solidsynth::io::vdb::to_bytes(&short, Default::default()),
        "holds 10 bytes",
    );
    let nan_voxels = solidsynth::io::vdb::VdbOptions {
        voxel_size: f64::NAN,
        ..Default::default()
    };
    refused(
        solidsynth::io::vdb::to_bytes(&Volume::new(2, 2, 2, 1), nan_voxels),
        "VDB voxel size",
    );
    refused(
        solidsynth::lapped::exemplar::SolidExemplar::from_volume(&short, "solid exemplar"),
        "holds 10 bytes",
    );
    refused(
        solidsynth::io::zarr::Layout::new([8, 8, 8], 3, 0),
        "chunk 0",
    );
    let layout = solidsynth::io::zarr::Layout::new([u32::MAX; 3], 4, 1).unwrap();
    assert_eq!(layout.chunk_count(), u64::MAX, "saturates, not wraps");

    // Gradient synthesis levels and masks.
    use solidsynth::gradient::synth::{GradientSynthParams, LevelSpec, MaskedExemplar};
    let params = GradientSynthParams {
        levels: vec![LevelSpec {
            spacing: u32::MAX,
            size: u32::MAX,
        }],
        ..Default::default()
    };
    refused(params.validate(), "odd slice size in 3..=63");
    let exemplar = common::fixture("marble32.png");
    let no_channels = Image {
        channels: 0,
        pixels: vec![],
        ..exemplar.clone()
    };
    refused(
        MaskedExemplar::new(&exemplar, &no_channels, "--mask m.png"),
        "image has 0 channels",
    );

    // Gray and alpha become gray RGB with that alpha.
    let gray_alpha = Image {
        width: 1,
        height: 1,
        channels: 2,
        pixels: vec![70, 9],
    };
    assert_eq!(gray_alpha.with_channels(3).pixels, [70, 70, 70]);
    assert_eq!(gray_alpha.with_channels(4).pixels, [70, 70, 70, 9]);
    assert_eq!(gray_alpha.with_channels(1).pixels, [70]);
}
