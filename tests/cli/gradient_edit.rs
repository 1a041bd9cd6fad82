//! `gradient edit`: strokes recolour a solid where they reach it; strokes, colours and flags it
//! cannot use are refused, and nothing is written.

use super::*;

fn edit(solid: &Path, strokes: &Path, color: &str, out: &Path) -> std::process::Output {
    let path = |p: &Path| p.to_str().unwrap().to_string();
    run(&[
        "gradient",
        "edit",
        &path(solid),
        "--strokes",
        &path(strokes),
        "--color",
        color,
        "-o",
        &path(out),
    ])
}

#[test]
fn strokes_recolour_the_solid_and_bad_edits_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let solid = d.join("g.gsolid");
    let o = run(&[
        "gradient",
        "synth",
        "--size",
        "16",
        "--backend",
        "cpu",
        "-o",
        solid.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let strokes = d.join("s.json");
    let at_8 = r#"{"strokes": [{"position": [8, 8, 8], "strength": 1.0}]}"#;
    std::fs::write(&strokes, at_8).unwrap();
    let edited = d.join("e.gsolid");
    let o = edit(&solid, &strokes, "255,0,255", &edited);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let e =
        solidsynth::gradient::format::from_bytes(&std::fs::read(&edited).unwrap(), "e").unwrap();
    let mut at_stroke = [0f32; 3];
    e.eval([8.0, 8.0, 8.0], &mut at_stroke);
    assert!(
        at_stroke[0] > 200.0 && at_stroke[2] > 200.0 && at_stroke[1] < 60.0,
        "{at_stroke:?}"
    );
    // (The solid is periodic: a stroke anywhere in space reaches it; one of strength 0 not.)
    let none = r#"{"strokes": [{"position": [8, 8, 8], "strength": 0.0}]}"#;
    for (text, color, needle) in [
        (r#"{"strokes": []}"#, "255,0,255", "no strokes"),
        (none, "255,0,255", "the strokes change no control point"),
        (at_8, "300,0,255", "--color 300,0,255"),
        (at_8, "1e39,0,0", "--color 1e39,0,0"),
    ] {
        std::fs::write(&strokes, text).unwrap();
        let out = d.join("x.gsolid");
        assert_user_error(
            &edit(&solid, &strokes, color, &out),
            needle,
            d,
            &["g.gsolid", "e.gsolid", "s.json"],
        );
    }
    // The slice's placement flags without a slice.
    let o = run(&[
        "gradient",
        "render",
        solid.to_str().unwrap(),
        "--origin",
        "1,2,3",
        "-o",
        d.join("v.nrrd").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--normal"));
    assert!(!d.join("v.nrrd").exists());
}
