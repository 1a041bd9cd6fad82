//! Cuts and volumes as the viewer asks for them: sizes, determinism, slices of the served volume, every download format, concurrent requests, the GPU's bytes.

use super::*;

#[test]
fn a_cut_is_a_png_of_the_asked_size_and_deterministic() {
    let (addr, solid) = server();
    let q = "origin=8,8,5.5&normal=0.6,0,0.8&size=24";
    let a = get(addr, &cut_path(solid, q));
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    assert_eq!(a.header("content-type"), Some("image/png"));
    let img = image::load_from_memory(&a.body).unwrap();
    assert_eq!((img.width(), img.height()), (24, 24));
    let ms: f64 = a.header("x-synthesis-ms").unwrap().parse().unwrap();
    assert!(ms > 0.0);
    let frame: serde_json::Value = serde_json::from_str(a.header("x-cut-frame").unwrap()).unwrap();
    assert_eq!(frame["n"][2].as_f64().unwrap(), 0.8);
    // Same parameters, same bytes (percent-encoded commas are the same request).
    let b = get(
        addr,
        &cut_path(solid, "origin=8%2C8%2C5.5&normal=0.6,0,0.8&size=24"),
    );
    assert_eq!(a.body, b.body);
    // Another plane, another image.
    let c = get(
        addr,
        &cut_path(solid, "origin=8,8,9.5&normal=0.6,0,0.8&size=24"),
    );
    assert_eq!(c.status, 200);
    assert_ne!(a.body, c.body);
}

#[test]
fn an_axis_aligned_cut_is_a_slice_of_the_served_volume() {
    let (addr, solid) = server();
    let r = get(addr, &format!("/api/solids/{solid}/volume?format=raw"));
    assert_eq!(r.status, 200);
    let n = PREVIEW as usize;
    assert_eq!(r.body.len(), n * n * n * 4);
    let cut = get(
        addr,
        &cut_path(solid, "origin=8,8,5.5&normal=0,0,1&size=16"),
    );
    assert_eq!(cut.status, 200);
    let img = image::load_from_memory(&cut.body).unwrap().to_rgba8();
    for y in 0..n {
        for x in 0..n {
            let i = ((5 * n + y) * n + x) * 4;
            assert_eq!(
                img.get_pixel(x as u32, y as u32).0,
                r.body[i..i + 4],
                "({x}, {y})"
            );
        }
    }
}

#[test]
fn volumes_download_in_every_format_and_read_back_equal() {
    let (addr, solid) = server();
    let nrrd = get(addr, &format!("/api/solids/{solid}/volume?format=nrrd"));
    assert_eq!(nrrd.status, 200);
    let v = solidsynth::io::nrrd::parse(&nrrd.body).unwrap();
    assert_eq!(v.dims(), [PREVIEW; 3]);
    let vti = get(addr, &format!("/api/solids/{solid}/volume?format=vti"));
    assert_eq!(
        solidsynth::io::vti::from_bytes(&vti.body, "vti").unwrap(),
        v
    );
    let flip = get(addr, &format!("/api/solids/{solid}/volume?format=flipbook"));
    let img = image::load_from_memory(&flip.body).unwrap().to_rgba8();
    assert_eq!(
        solidsynth::io::flipbook::from_image(&img, PREVIEW, v.channels).unwrap(),
        v
    );
    // The command line's other writers: NumPy (its header, then the NRRD order), a TIFF stack
    // (read back by the tiff crate, page by page) and a KTX2 3D texture.
    let npy = get(addr, &format!("/api/solids/{solid}/volume?format=npy"));
    assert_eq!(npy.status, 200);
    assert!(npy.body.starts_with(b"\x93NUMPY"));
    assert_eq!(&npy.body[npy.body.len() - v.data.len()..], &v.data[..]);
    let tif = get(addr, &format!("/api/solids/{solid}/volume?format=tiff"));
    assert_eq!(tif.status, 200);
    let mut decoder = tiff::decoder::Decoder::new(std::io::Cursor::new(&tif.body)).unwrap();
    let mut pages = Vec::new();
    loop {
        match decoder.read_image().unwrap() {
            tiff::decoder::DecodingResult::U8(page) => pages.extend(page),
            _ => panic!("8-bit pages"),
        }
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().unwrap();
    }
    assert_eq!(pages, v.data);
    let ktx = get(addr, &format!("/api/solids/{solid}/volume?format=ktx2"));
    assert_eq!(ktx.status, 200);
    let reader = ktx2::Reader::new(&ktx.body[..]).unwrap();
    assert_eq!(reader.header().pixel_depth, PREVIEW);
    // Another size is synthesized on demand: the same solid, so the preview is its corner.
    let big = get(
        addr,
        &format!("/api/solids/{solid}/volume?format=nrrd&size=20"),
    );
    assert_eq!(big.status, 200);
    let big = solidsynth::io::nrrd::parse(&big.body).unwrap();
    assert_eq!(big.dims(), [20; 3]);
    assert_eq!(big.at(3, 7, 11), v.at(3, 7, 11));
    assert_error(
        &get(addr, &format!("/api/solids/{solid}/volume?size=33")),
        400,
        "size",
    );
    assert_error(
        &get(addr, &format!("/api/solids/{solid}/volume?format=obj")),
        400,
        "format",
    );
}

#[test]
fn concurrent_cuts_queue_and_all_succeed() {
    let (addr, solid) = server();
    let results: Vec<(u16, Vec<u8>)> = std::thread::scope(|s| {
        let hs: Vec<_> = (0..8)
            .map(|i| {
                s.spawn(move || {
                    let q = format!("origin=8,8,{}&normal=0,0.6,0.8&size=32", i % 4);
                    let r = get(addr, &cut_path(solid, &q));
                    (r.status, r.body)
                })
            })
            .collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (i, (status, body)) in results.iter().enumerate() {
        assert_eq!(
            *status,
            200,
            "request {i}: {}",
            String::from_utf8_lossy(body)
        );
    }
    // Requests for the same plane got the same bytes, whatever the interleaving.
    assert_eq!(results[0].1, results[4].1);
    assert_ne!(results[0].1, results[1].1);
}

#[test]
fn a_gpu_server_cuts_the_same_bytes_as_the_cpu_one() {
    use solidsynth::backend::BackendChoice;
    let (cpu_addr, cpu_solid) = server();
    let compute = match Compute::open(BackendChoice::Gpu, &solidsynth::gpu::GpuOptions::from_env())
    {
        Ok(c) => c,
        Err(e) => {
            assert!(std::env::var_os("CI").is_none(), "no GPU in CI: {e}");
            eprintln!("SKIPPED the GPU server (no adapter, CI unset): {e}");
            return;
        }
    };
    let config = ServeConfig {
        port: 0,
        preview_size: PREVIEW,
        ..ServeConfig::default()
    };
    let (server, gpu_solid) = start_with_solid(config, compute);
    let addr = server.addr();
    assert!(get(addr, "/api/state").json()["backend"]
        .as_str()
        .unwrap()
        .starts_with("gpu"));
    let q = "origin=7,9,6.5&normal=0,0.6,0.8&size=20";
    let a = get(cpu_addr, &cut_path(cpu_solid, q));
    let b = get(addr, &cut_path(gpu_solid, q));
    assert_eq!((a.status, b.status), (200, 200));
    assert_eq!(a.body, b.body, "GPU and CPU cuts differ");
    server.shutdown();
}
