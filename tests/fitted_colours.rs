//! `--color fitted`: each voxel's three exemplar pixels weighted by how well each plane's 5x5
//! neighbourhood of mean colours fits its exemplar there. The colours follow the rule exactly
//! (recomputed here from the triples), and the solid stays a function of space: boxes, groups,
//! cuts and tileable pieces agree, since a request plans the neighbours the colours read.

mod common;

use solidsynth::analysis::frame::unpack;
use solidsynth::analysis::Analysis;
use solidsynth::backend::Compute;
use solidsynth::exemplar::{Border, Image};
use solidsynth::lazy::cut::{CutSession, CutSpec};
use solidsynth::lazy::{Box3, ColorSource, SynthOptions, SynthParams, Synthesizer};
use solidsynth::volume::Volume;

use common::voxel_at;

fn params(seed: u64) -> SynthParams {
    SynthParams {
        seed,
        color: ColorSource::Fitted,
        ..Default::default()
    }
}

fn synth(a: &Analysis, params: &SynthParams, b: Box3, options: SynthOptions) -> Volume {
    let mut s = Synthesizer::with_options(a, params.clone(), &Compute::Cpu, options).unwrap();
    s.synthesize(b, &|_, _| {}).unwrap()
}

/// Three different exemplars from one fixture: itself, its transpose and its channels rotated,
/// so a rule that paired a plane with another plane's exemplar would fail.
fn three_exemplars() -> Vec<Image> {
    let img = common::fixture("cells32.png");
    let (w, c) = (img.width, img.channels as usize);
    let mut transposed = img.clone();
    let mut rotated = img.clone();
    for y in 0..img.height {
        for x in 0..w {
            let i = (y * w + x) as usize * c;
            transposed.pixels[i..i + c].copy_from_slice(img.at(y, x));
            for k in 0..c.min(3) {
                rotated.pixels[i + k] = img.at(x, y)[(k + 1) % c.min(3)];
            }
        }
    }
    vec![img, transposed, rotated]
}

/// The rule, written out again from its description: for the voxels whose 5x5 planes lie
/// inside the box, the colour from the triples (mean colours (sum + 1) / 3 per channel, misfits
/// against the exemplars' windows with their border, weights q^2 with q = 256 (D_min + 1) /
/// (D_a + 1)).
#[test]
fn fitted_colours_follow_the_rule() {
    let a = common::analyze(three_exemplars(), Border::Mirror);
    let b = Box3::new([-4, 3, -6], [8, 15, 6]);
    let mut s = Synthesizer::new(&a, params(4), &Compute::Cpu).unwrap();
    let (v, triples) = s.synthesize_with_triples(b, &|_, _| {}).unwrap();
    let mut average = Synthesizer::new(
        &a,
        SynthParams {
            color: ColorSource::Average,
            ..params(4)
        },
        &Compute::Cpu,
    )
    .unwrap();
    let means = average.synthesize(b, &|_, _| {}).unwrap();
    let [nx, ny] = [v.nx as i32, v.ny as i32];
    let triple = |p: [i32; 3]| {
        let i = (((p[2] - b.lo[2]) * ny + (p[1] - b.lo[1])) * nx + (p[0] - b.lo[0])) as usize;
        &triples[i * 3..i * 3 + 3]
    };
    let images: Vec<_> = (0..3).map(|e| &a.exemplar(e).levels[0].image).collect();
    let channels = v.channels as usize;
    let (mut checked, mut unlike_mean) = (0, 0);
    for z in b.lo[2] + 2..b.hi[2] - 2 {
        for y in b.lo[1] + 2..b.hi[1] - 2 {
            for x in b.lo[0] + 2..b.hi[0] - 2 {
                let p = [x, y, z];
                let t = triple(p);
                let mut misfit = [0u64; 3];
                let mut pixels = [[0u8; 4]; 3];
                for e in 0..3 {
                    let (ua, va) = ((e + 1) % 3, (e + 2) % 3);
                    let (px, py) = unpack(t[e]);
                    pixels[e][..channels].copy_from_slice(&images[e].at(px, py)[..channels]);
                    for dv in -2..=2 {
                        for du in -2..=2 {
                            let mut n = p;
                            n[ua] += du;
                            n[va] += dv;
                            let window =
                                images[e].at_border(px as i32 + du, py as i32 + dv, Border::Mirror);
                            for c in 0..channels {
                                let d = voxel_at(&means, b, n)[c] as i64 - window[c] as i64;
                                misfit[e] += (d * d) as u64;
                            }
                        }
                    }
                }
                let best = *misfit.iter().min().unwrap();
                let w = misfit.map(|d| ((best + 1) * 256 / (d + 1)).pow(2));
                let total: u64 = w.iter().sum();
                for c in 0..channels {
                    let sum: u64 = (0..3).map(|e| w[e] * pixels[e][c] as u64).sum();
                    let want = ((sum + total / 2) / total) as u8;
                    assert_eq!(voxel_at(&v, b, p)[c], want, "voxel {p:?} channel {c}");
                }
                checked += 1;
                unlike_mean += usize::from(voxel_at(&v, b, p) != voxel_at(&means, b, p));
            }
        }
    }
    // The rule is not the mean in disguise: it changes a share of the voxels (the triples are
    // the same solid's).
    assert!(checked > 500, "{checked} voxels checked");
    assert!(
        unlike_mean * 20 > checked && unlike_mean < checked,
        "{unlike_mean} of {checked} voxels differ from the mean"
    );
}

/// Any box equals the same voxels of a larger box, in groups too (own or shared coarse levels),
/// and cuts (axis-aligned boxes, oblique samples) equal the voxels they sample.
#[test]
fn fitted_solids_are_spatially_deterministic() {
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = params(6);
    let big = Box3::new([-10, -4, -7], [12, 14, 9]);
    let v = synth(&a, &params, big, SynthOptions::default());
    for small in [
        Box3::new([0, 0, 0], [7, 5, 3]),
        Box3::new([-10, -4, -7], [-6, 1, -2]),
        Box3::new([3, 11, 6], [12, 14, 9]),
        Box3::new([-1, -1, -1], [0, 0, 0]),
    ] {
        let s = synth(&a, &params, small, SynthOptions::default());
        for z in small.lo[2]..small.hi[2] {
            for y in small.lo[1]..small.hi[1] {
                for x in small.lo[0]..small.hi[0] {
                    let p = [x, y, z];
                    assert_eq!(
                        voxel_at(&s, small, p),
                        voxel_at(&v, big, p),
                        "{p:?} of {small:?}"
                    );
                }
            }
        }
    }
    for shared in [false, true] {
        let options = SynthOptions {
            max_group: Some(8),
            shared_coarse_levels: Some(shared),
            ..Default::default()
        };
        assert!(
            synth(&a, &params, big, options) == v,
            "groups of 8, shared {shared}"
        );
    }
    let mut session = CutSession::new(Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap());
    for (normal, spacing) in [([0.0, 0.0, 1.0], 1.0), ([0.4, 1.0, -0.7], 0.9)] {
        let spec = CutSpec {
            origin: [0.3, 3.0, 0.4],
            normal,
            up: None,
            size: 10,
            spacing,
        };
        let img = session.cut(&spec).unwrap();
        common::assert_cut_samples_box(&img, &spec, &v, big);
    }
}

/// A tileable solid's fitted colours read across its period: in one piece (reads wrapped) and
/// in groups (boxes of the periodic solid with their padding) they are the same bytes.
#[test]
fn fitted_tileable_solids_wrap() {
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = params(3);
    let mut whole = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    let one_piece = whole.synthesize_tileable(32, &|_, _| {}, false).unwrap().0;
    let options = SynthOptions {
        max_group: Some(16),
        shared_coarse_levels: Some(false),
        ..Default::default()
    };
    let mut grouped = Synthesizer::with_options(&a, params, &Compute::Cpu, options).unwrap();
    let in_groups = grouped
        .synthesize_tileable(32, &|_, _| {}, false)
        .unwrap()
        .0;
    assert_eq!(grouped.last_stats().unwrap().groups, 8);
    assert!(
        in_groups.data == one_piece.data,
        "grouped tileable solid differs"
    );
}
