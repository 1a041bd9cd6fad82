//! Fitting a capture: exact biquadratics, refused light sets, and the light files.

use super::*;

#[test]
fn fit_reproduces_the_capture() {
    let cap = capture::synthetic(48, 20, 3);
    for format in [PtmFormat::Lrgb, PtmFormat::Rgb] {
        let ptm = fit::fit(&cap, format, "capture").unwrap();
        let rms = fit::rms_error(&cap, &ptm);
        // Lambertian shading with cast shadows is not biquadratic: a few levels of error.
        assert!(rms < 16.0, "{format:?}: RMS {rms}");
    }
}

#[test]
fn fit_recovers_exact_biquadratics() {
    // Images that are exactly a biquadratic of the light per pixel and channel: the RGB fit
    // recovers them within 8-bit rounding and coefficient quantization.
    let lights = capture::spiral_lights(12);
    let (w, h) = (8u32, 6u32);
    let mut rng = SeededRng::new(5);
    let polys: Vec<[f64; 6]> = (0..w * h * 3)
        .map(|_| {
            let r = |rng: &mut SeededRng, s: f64| (rng.below(2001) as f64 / 1000.0 - 1.0) * s;
            [
                r(&mut rng, 0.1),
                r(&mut rng, 0.1),
                r(&mut rng, 0.1),
                r(&mut rng, 0.15),
                r(&mut rng, 0.15),
                0.5 + r(&mut rng, 0.1),
            ]
        })
        .collect();
    let images = lights
        .iter()
        .map(|l| {
            image::RgbImage::from_fn(w, h, |x, y| {
                image::Rgb([0, 1, 2].map(|c| {
                    let a = &polys[((y * w + x) * 3 + c) as usize];
                    let v = a[0] * l.lu * l.lu
                        + a[1] * l.lv * l.lv
                        + a[2] * l.lu * l.lv
                        + a[3] * l.lu
                        + a[4] * l.lv
                        + a[5];
                    (v * 255.0).round() as u8
                }))
            })
        })
        .collect();
    let cap = Capture {
        images,
        lights: lights.clone(),
        names: (0..12).map(|i| format!("{i}.png")).collect(),
    };
    let ptm = fit::fit(&cap, PtmFormat::Rgb, "exact").unwrap();
    assert!(fit::rms_error(&cap, &ptm) < 1.0);
    // And at a light between the captured ones.
    let c = ptm.shade(3, 2, 0.2, -0.1);
    let a = &polys[((2 * w + 3) * 3) as usize];
    let want = a[0] * 0.04 + a[1] * 0.01 + a[2] * -0.02 + a[3] * 0.2 + a[4] * -0.1 + a[5];
    assert!((c[0] as f64 - want).abs() < 0.01, "{} vs {want}", c[0]);
}

#[test]
fn degenerate_and_too_few_lights_are_refused() {
    let one_elevation: Vec<Light> = (0..12)
        .map(|i| {
            let p = i as f64 * 0.5;
            Light {
                lu: 0.6 * p.cos(),
                lv: 0.6 * p.sin(),
            }
        })
        .collect();
    let e = fit::pseudo_inverse(&one_elevation, "lights")
        .unwrap_err()
        .to_string();
    assert!(e.contains("degenerate") && e.contains("lights"), "{e}");
    let on_a_line: Vec<Light> = (0..10)
        .map(|i| Light {
            lu: i as f64 / 10.0 - 0.45,
            lv: 0.0,
        })
        .collect();
    assert!(fit::pseudo_inverse(&on_a_line, "l")
        .unwrap_err()
        .to_string()
        .contains("degenerate"));
    assert!(fit::pseudo_inverse(&capture::spiral_lights(5), "l").is_err());
    assert!(fit::pseudo_inverse(&capture::spiral_lights(6), "l").is_ok());
    let mut cap = capture::synthetic(16, 8, 0);
    cap.images.truncate(5);
    cap.lights.truncate(5);
    assert!(fit::fit(&cap, PtmFormat::Lrgb, "c")
        .unwrap_err()
        .to_string()
        .contains("at least 6"));
    let mut cap = capture::synthetic(16, 8, 0);
    cap.images[3] = image::RgbImage::new(16, 15);
    assert!(fit::fit(&cap, PtmFormat::Lrgb, "c")
        .unwrap_err()
        .to_string()
        .contains("one size"));
}

#[test]
fn light_files_parse_and_mismatches_are_named() {
    let lp = "3\na.png 0 0 1\nb.png 1 0 1\nc.png 0 -1 1\n";
    let l = capture::parse_lights(lp, "f", false).unwrap();
    assert_eq!(l.len(), 3);
    assert!((l[1].1.lu - 0.5f64.sqrt()).abs() < 1e-12);
    assert!((l[2].1.lv + 0.5f64.sqrt()).abs() < 1e-12);
    assert!(capture::parse_lights("4\na.png 0 0 1\n", "f", false)
        .unwrap_err()
        .to_string()
        .contains("announces 4"));
    assert!(capture::parse_lights("1\na.png 0 0 -1\n", "f", false)
        .unwrap_err()
        .to_string()
        .contains("z > 0"));
    let json = r#"{"lights": [{"file": "a.png", "lu": 0.1, "lv": 0.2}, {"file": "b.png", "direction": [0, 1, 1]}]}"#;
    let l = capture::parse_lights(json, "f", true).unwrap();
    assert_eq!(l[0].1, Light { lu: 0.1, lv: 0.2 });
    assert!(capture::parse_lights(
        r#"{"lights": [{"file": "a", "lu": 1, "lv": 1}]}"#,
        "f",
        true
    )
    .is_err());
    let refusal = |text: &str, json: bool| {
        capture::parse_lights(text, "f", json)
            .unwrap_err()
            .to_string()
    };
    // Every entry of a direction is a number (a string was dropped, leaving x, z as the light).
    let e = refusal(
        r#"{"lights": [{"file": "a", "direction": [0.9, "y", 0, 0.3]}]}"#,
        true,
    );
    assert!(e.contains("needs 3 numbers"), "{e}");
    // Huge numbers are printed short, and a huge direction is still a direction.
    let e = refusal(r#"{"lights": [{"file": "a", "lu": 1e300, "lv": 0}]}"#, true);
    assert!(e.contains("(1e300, 0) is outside"), "{e}");
    let far = capture::parse_lights(
        "1
a.png 1e300 0 1e300
",
        "f",
        false,
    )
    .unwrap();
    assert!((far[0].1.lu - 0.5f64.sqrt()).abs() < 1e-12);
    // Line numbers count comments and blank lines.
    let e = refusal(
        "# lights

2
a.png 0 0 1

b.png 0 0
",
        false,
    );
    assert!(e.contains("line 6"), "{e}");
}
