//! The colours of a solid: explained by its triples, matched to the exemplar's contrast, taken per channel from their sources.

use super::*;

/// The triples returned with a volume explain its colours: each voxel is the rounded mean of the
/// three finest-level exemplar pixels its triple names (also across chunk seams).
#[test]
fn triples_explain_the_colours() {
    use solidsynth::analysis::frame::unpack;
    use solidsynth::backend::Compute;
    use solidsynth::lazy::{Box3, SynthOptions, SynthParams, Synthesizer};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let mut s = Synthesizer::with_options(
        &a,
        SynthParams {
            seed: 4,
            ..Default::default()
        },
        &Compute::Cpu,
        SynthOptions {
            max_group: Some(8),
            ..Default::default()
        },
    )
    .unwrap();
    let b = Box3::new([-3, 2, 7], [7, 11, 15]);
    let (v, triples) = s.synthesize_with_triples(b, &|_, _| {}).unwrap();
    assert_eq!(triples.len() as u64, b.voxels() * 3);
    let img = &a.exemplar(0).levels[0].image;
    for (i, t) in triples.chunks_exact(3).enumerate() {
        let (x, y, z) = (
            i as u32 % v.nx,
            i as u32 / v.nx % v.ny,
            i as u32 / (v.nx * v.ny),
        );
        for ch in 0..3 {
            let sum: u32 = t
                .iter()
                .map(|&c| unpack(c))
                .map(|(px, py)| img.at(px, py)[ch] as u32)
                .sum();
            assert_eq!(
                v.at(x, y, z)[ch] as u32,
                (sum + 1) / 3,
                "voxel {i} channel {ch}"
            );
        }
    }
}

/// `--color matched` recolours the same solid: one table per channel (the same mean gives the
/// same colour everywhere, sub-boxes included), monotone, and the colours' spread that of the
/// exemplar (on the probe it is estimated from, and near it on a box).
#[test]
fn matched_colours_restore_the_exemplar_contrast() {
    use solidsynth::backend::Compute;
    use solidsynth::lazy::{Box3, ColorSource, SynthParams, Synthesizer};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let synth = |color, b| {
        let params = SynthParams {
            seed: 6,
            color,
            ..Default::default()
        };
        Synthesizer::new(&a, params, &Compute::Cpu)
            .unwrap()
            .synthesize(b, &|_, _| {})
            .unwrap()
    };
    let b = Box3::new([-4, 0, 3], [36, 40, 43]);
    let (mean, matched) = (
        synth(ColorSource::Average, b),
        synth(ColorSource::Matched, b),
    );
    let channels = mean.channels as usize;
    assert_eq!(channels, 3);
    let mut table = [[None::<u8>; 256]; 3];
    for (m, t) in mean.data.chunks_exact(3).zip(matched.data.chunks_exact(3)) {
        for ch in 0..3 {
            let slot = &mut table[ch][m[ch] as usize];
            assert_eq!(
                *slot.get_or_insert(t[ch]),
                t[ch],
                "channel {ch}, mean {}",
                m[ch]
            );
        }
    }
    for column in &table {
        let seen: Vec<u8> = column.iter().flatten().copied().collect();
        assert!(
            seen.windows(2).all(|w| w[0] <= w[1]),
            "not monotone: {seen:?}"
        );
    }
    // Total standard deviation of the colour channels.
    let spread = |bytes: &[u8], stride: usize| {
        (0..3)
            .map(|ch| {
                let v: Vec<f64> = bytes.chunks_exact(stride).map(|p| p[ch] as f64).collect();
                let m = v.iter().sum::<f64>() / v.len() as f64;
                v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64
            })
            .sum::<f64>()
            .sqrt()
    };
    let img = common::fixture("cells32.png");
    let (e, m, t) = (
        spread(&img.pixels, img.channels as usize),
        spread(&mean.data, 3),
        spread(&matched.data, 3),
    );
    eprintln!("colour spread: exemplar {e:.1}, mean {m:.1}, matched {t:.1}");
    // (This fixture's mean keeps most of its contrast, 73.0 against 74.1, so the box is only
    // checked to be near the exemplar; the photographs' gains are measured in BENCHMARKS.md,
    // and the probe below must match closely.)
    assert!(
        (t - e).abs() < 0.03 * e,
        "exemplar {e:.1}, mean {m:.1}, matched {t:.1}"
    );
    // The probe itself (a tileable solid of the same parameters, 64^3 for a 32^2 exemplar)
    // gets the exemplar's spread, up to rounding and clamping.
    let params = SynthParams {
        seed: 6,
        color: ColorSource::Matched,
        ..Default::default()
    };
    let probe = Synthesizer::new(&a, params, &Compute::Cpu)
        .unwrap()
        .synthesize_tileable(64, &|_, _| {}, false)
        .unwrap()
        .0;
    let p = spread(&probe.data, 3);
    eprintln!("probe spread, matched: {p:.1}");
    assert!(
        (p - e).abs() < 0.02 * e,
        "exemplar {e:.1}, matched probe {p:.1}"
    );
    // Spatially deterministic: a sub-box is the same voxels of the box.
    let sub = Box3::new([0, 5, 10], [9, 13, 17]);
    let part = synth(ColorSource::Matched, sub);
    for z in 0..7u32 {
        for y in 0..8u32 {
            for x in 0..9u32 {
                assert_eq!(part.at(x, y, z), matched.at(x + 4, y + 5, z + 7));
            }
        }
    }
}

/// `--color x,matched,average`: each colour channel is that channel of the solid coloured by its
/// own source, and a list whose length is not the colour channel count is refused.
#[test]
fn per_channel_colours_take_each_channel_from_its_source() {
    use solidsynth::backend::Compute;
    use solidsynth::lazy::{Box3, ColorSource, SynthParams, Synthesizer};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let synth = |color: ColorSource| {
        let params = SynthParams {
            seed: 9,
            color,
            ..Default::default()
        };
        Synthesizer::new(&a, params, &Compute::Cpu)?
            .synthesize(Box3::new([-3, 2, 0], [9, 11, 6]), &|_, _| {})
    };
    let per: ColorSource = "x,matched,average".parse().unwrap();
    assert_eq!(per.to_string(), "x,matched,average");
    let mixed = synth(per).unwrap();
    let sources = [ColorSource::X, ColorSource::Matched, ColorSource::Average];
    let singles: Vec<_> = sources.iter().map(|&c| synth(c).unwrap()).collect();
    for (k, p) in mixed.data.chunks_exact(3).enumerate() {
        for (ch, single) in singles.iter().enumerate() {
            assert_eq!(p[ch], single.data[k * 3 + ch], "voxel {k}, channel {ch}");
        }
    }
    // The sources differ channel by channel, so the comparison above could fail.
    let channel = |v: &solidsynth::volume::Volume, ch: usize| -> Vec<u8> {
        v.data.chunks_exact(3).map(|p| p[ch]).collect()
    };
    assert_ne!(channel(&singles[0], 0), channel(&singles[2], 0));
    assert_ne!(channel(&singles[1], 1), channel(&singles[2], 1));
    // Two sources for three colour channels: refused, naming the flag.
    let err = synth("x,y".parse().unwrap()).unwrap_err().to_string();
    assert!(
        err.contains("--color x,y") && err.contains("3 colour channels"),
        "{err}"
    );
    // Parsing: single names, lists of 2 to 4, nothing else.
    assert_eq!("z".parse::<ColorSource>().unwrap(), ColorSource::Z);
    for bad in ["", "q", "x,q", "x,y,z,x,y", "x,,y"] {
        assert!(bad.parse::<ColorSource>().is_err(), "{bad:?} parsed");
    }
}
