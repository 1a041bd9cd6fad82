//! Spatial determinism: any box, cut or schedule of the solid equals the same voxels of any
//! larger request, and the same inputs repeat it.

use super::common;
use solidsynth::backend::Compute;
use solidsynth::exemplar::Border;
use solidsynth::lazy::{Box3, SynthOptions, SynthParams, Synthesizer};
use solidsynth::volume::Volume;

fn synth(
    a: &solidsynth::analysis::Analysis,
    params: &SynthParams,
    b: Box3,
    chunk: Option<u32>,
) -> Volume {
    let options = SynthOptions {
        max_group: chunk,
        ..Default::default()
    };
    let mut s = Synthesizer::with_options(a, params.clone(), &Compute::Cpu, options).unwrap();
    s.synthesize(b, &|_, _| {}).unwrap()
}

/// Voxels of `small` (box `sb`) equal the same voxels of `big` (box `bb`).
fn assert_contained(big: &Volume, bb: Box3, small: &Volume, sb: Box3) {
    for z in sb.lo[2]..sb.hi[2] {
        for y in sb.lo[1]..sb.hi[1] {
            for x in sb.lo[0]..sb.hi[0] {
                let p = [x, y, z];
                let (s, g) = (common::voxel_at(small, sb, p), common::voxel_at(big, bb, p));
                assert_eq!(s, g, "voxel ({x},{y},{z}) of {sb:?} differs inside {bb:?}");
            }
        }
    }
}

/// A warm session's cuts equal the voxels they sample in a box around them: axis-aligned
/// ones at spacing 1 (synthesized as one-voxel-thick boxes) in every orientation, and an
/// oblique one (sampled voxel by voxel), one after the other in the same session.
#[test]
fn cuts_equal_the_voxels_they_sample() {
    use solidsynth::lazy::cut::{CutSession, CutSpec};
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = SynthParams {
        seed: 9,
        ..Default::default()
    };
    let big = Box3::new([-9, -6, -8], [9, 10, 8]);
    let v = synth(&a, &params, big, None);
    let mut session = CutSession::new(Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap());
    let specs = [
        ([0.0, 0.0, 1.0], None, 1.0),
        ([0.0, 0.0, -1.0], Some([1.0, 0.0, 0.0]), 1.0),
        ([0.0, 1.0, 0.0], None, 1.0),
        ([-1.0, 0.0, 0.0], Some([0.0, -1.0, 0.0]), 1.0),
        ([0.4, 1.0, -0.7], None, 0.9),
    ];
    for (normal, up, spacing) in specs {
        let spec = CutSpec {
            origin: [0.3, 2.0, -0.6],
            normal,
            up,
            size: 12,
            spacing,
        };
        let img = session.cut(&spec).unwrap();
        common::assert_cut_samples_box(&img, &spec, &v, big);
    }
}

#[test]
fn any_box_equals_the_same_voxels_of_a_larger_box() {
    let a = common::analyze(vec![common::fixture("cells32.png")], Border::Wrap);
    let params = SynthParams {
        seed: 5,
        ..Default::default()
    };
    let big = Box3::new([-12, -4, -9], [14, 18, 11]);
    let v = synth(&a, &params, big, None);
    for small in [
        Box3::new([0, 0, 0], [9, 7, 5]),
        Box3::new([-12, -4, -9], [-3, 1, -2]),
        Box3::new([3, 11, 6], [14, 18, 11]),
        Box3::new([-1, -1, -1], [1, 1, 1]),
    ] {
        assert_contained(&v, big, &synth(&a, &params, small, None), small);
    }
    // And random boxes inside it (seeded: the same ones every run), which land across
    // brick boundaries and on negative coordinates as they fall.
    let mut rng = solidsynth::util::hash::SeededRng::new(11);
    for _ in 0..6 {
        let lo = [0, 1, 2].map(|i| big.lo[i] + rng.below((big.hi[i] - big.lo[i]) as u64) as i32);
        let hi = [0, 1, 2].map(|i| (lo[i] + 1 + rng.below(9) as i32).min(big.hi[i]));
        let small = Box3::new(lo, hi);
        assert_contained(&v, big, &synth(&a, &params, small, None), small);
    }
    // Grouping (seams at multiples of 12 voxels) changes nothing, whether each group
    // synthesizes its own coarse levels or all share them (each level above the finest
    // synthesized once, itself in groups of 12 down to l_start).
    let mut own = Synthesizer::with_options(
        &a,
        params.clone(),
        &Compute::Cpu,
        SynthOptions {
            max_group: Some(12),
            shared_coarse_levels: Some(false),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(own.synthesize(big, &|_, _| {}).unwrap(), v);
    let mut shared = Synthesizer::with_options(
        &a,
        params.clone(),
        &Compute::Cpu,
        SynthOptions {
            max_group: Some(12),
            shared_coarse_levels: Some(true),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(shared.synthesize(big, &|_, _| {}).unwrap(), v);
    let (own, shared) = (own.last_stats().unwrap(), shared.last_stats().unwrap());
    assert!(shared.groups > 1);
    // Fewer coarse voxels than the groups' own coarse levels hold (groups this small still
    // pad every level's own groups: 1.4 M against 2.1 M at l_start).
    for l in 0..3 {
        assert!(
            shared.voxels_per_level[l] < own.voxels_per_level[l],
            "{shared:?} vs {own:?}"
        );
    }
    // Streamed in slabs of groups (what `synth` writes to its file): the slabs follow each
    // other along z, span the box in x and y, and together are the volume.
    let mut s = Synthesizer::with_options(
        &a,
        params.clone(),
        &Compute::Cpu,
        SynthOptions {
            max_group: Some(8),
            ..Default::default()
        },
    )
    .unwrap();
    let mut joined = Vec::new();
    let mut next_z = 0;
    let mut depths = Vec::new();
    s.synthesize_slabs(big, &|_, _| {}, false, |slab| {
        assert_eq!(slab.z0, next_z);
        assert_eq!([slab.volume.nx, slab.volume.ny], [v.nx, v.ny]);
        assert!(slab.triples.is_empty());
        next_z += slab.volume.nz;
        depths.push(slab.volume.nz);
        joined.extend_from_slice(&slab.volume.data);
        Ok(())
    })
    .unwrap();
    assert_eq!(next_z, v.nz);
    // Groups start at the box's low brick corner (z -9 lies in the brick from -12): the
    // first slab holds 8 - 3 slices, then 8 each, then the rest.
    assert_eq!(depths, [5, 8, 7]);
    assert_eq!(joined, v.data);
    // Scattered voxels (sparse bricks, each with its own dependency set) equal the box's.
    let mut s = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    let mut rng = solidsynth::util::hash::SeededRng::new(3);
    let points: Vec<[i32; 3]> = (0..40)
        .map(|_| [0, 1, 2].map(|i| big.lo[i] + rng.below((big.hi[i] - big.lo[i]) as u64) as i32))
        .collect();
    let colors = s.sample(&points, &|_, _| {}).unwrap();
    // The same points in groups of 8 sharing their coarse levels (a sparse request's
    // parents: scattered bricks, not a box).
    let mut shared = Synthesizer::with_options(
        &a,
        params.clone(),
        &Compute::Cpu,
        SynthOptions {
            max_group: Some(8),
            shared_coarse_levels: Some(true),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(shared.sample(&points, &|_, _| {}).unwrap(), colors);
    assert!(shared.last_stats().unwrap().groups > 1);
    for (p, c) in points.iter().zip(&colors) {
        let want = v.at(
            (p[0] - big.lo[0]) as u32,
            (p[1] - big.lo[1]) as u32,
            (p[2] - big.lo[2]) as u32,
        );
        assert_eq!(&c.to_le_bytes()[..want.len()], want, "voxel {p:?}");
    }
    // A sparse request whose bounding box's dense plan exceeds the state limit but whose own
    // plan fits is one group (no padding at seams between groups); one byte less and it
    // is split into cubes. The same colours every way.
    let far = [
        points[0],
        [points[0][0] + 60, points[0][1] + 50, points[0][2] + 40],
    ];
    let mut one = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    let far_colors = one.sample(&far, &|_, _| {}).unwrap();
    // (The CPU backend's passes keep no pass-start copy: the peak is one state, what the
    // limit bounds.)
    let fitting = one.last_stats().unwrap().peak_state_bytes;
    let dense_bound =
        solidsynth::lazy::grouping::planned_state_bytes([64, 56, 48], &[2; 4], &[16; 4]);
    assert!(dense_bound > fitting, "{dense_bound} vs {fitting}");
    let mut limited = Synthesizer::with_options(
        &a,
        params.clone(),
        &Compute::Cpu,
        SynthOptions {
            state_limit: Some(fitting),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(limited.sample(&far, &|_, _| {}).unwrap(), far_colors);
    assert_eq!(limited.last_stats().unwrap().groups, 1);
    let mut split = Synthesizer::with_options(
        &a,
        params.clone(),
        &Compute::Cpu,
        SynthOptions {
            state_limit: Some(fitting - 1),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(split.sample(&far, &|_, _| {}).unwrap(), far_colors);
    assert!(split.last_stats().unwrap().groups > 1);
    // Storage follows the request: two scattered points cost less than the box around them
    // (40 points of this small box cost more: each brings its own dependency padding).
    let mut s = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    s.sample(&points[..2], &|_, _| {}).unwrap();
    let stats = s.last_stats().unwrap().clone();
    let mut dense = Synthesizer::new(&a, params.clone(), &Compute::Cpu).unwrap();
    dense.synthesize(big, &|_, _| {}).unwrap();
    let dense_stats = dense.last_stats().unwrap();
    assert!(
        stats.voxels_per_level[3] < dense_stats.voxels_per_level[3],
        "{stats:?} vs {dense_stats:?}"
    );
}

#[test]
fn mirrored_three_exemplar_solids_are_deterministic_too() {
    let ex = vec![
        common::fixture("cells32.png"),
        common::fixture("marble32.png"),
        common::fixture("cells32.png"),
    ];
    let a = common::analyze(ex, Border::Mirror);
    let params = SynthParams {
        seed: 9,
        jitter: 2.0,
        ..Default::default()
    };
    let big = Box3::new([30, -20, 0], [46, -6, 12]);
    let v = synth(&a, &params, big, Some(8));
    let small = Box3::new([33, -15, 4], [40, -9, 12]);
    assert_contained(&v, big, &synth(&a, &params, small, None), small);
}

#[test]
fn seed_and_jitter_change_the_solid_and_same_inputs_repeat_it() {
    let a = common::analyze(vec![common::fixture("marble32.png")], Border::Wrap);
    let b = Box3::new([0, 0, 0], [12, 12, 12]);
    let base = SynthParams {
        seed: 1,
        ..Default::default()
    };
    let v = synth(&a, &base, b, None);
    assert_eq!(v, synth(&a, &base, b, None));
    assert_ne!(
        v,
        synth(
            &a,
            &SynthParams {
                seed: 2,
                ..base.clone()
            },
            b,
            None
        )
    );
    assert_ne!(
        v,
        synth(
            &a,
            &SynthParams {
                jitter: 0.0,
                ..base.clone()
            },
            b,
            None
        )
    );
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    assert_eq!(
        v,
        one.install(|| synth(&a, &base, b, None)),
        "thread count changed the result"
    );
}

/// Per-level pass counts define other solids, each as spatially deterministic: the padding
/// each level plans follows its own passes.
#[test]
fn pass_schedules_are_other_solids_with_the_same_determinism() {
    use solidsynth::lazy::PassSchedule;
    let a = common::analyze(vec![common::fixture("marble32.png")], Border::Wrap);
    let big = Box3::new([-6, -2, -5], [10, 12, 9]);
    let small = Box3::new([1, 3, -4], [7, 8, 2]);
    let uniform = SynthParams {
        seed: 3,
        ..Default::default()
    };
    let v2 = synth(&a, &uniform, big, None);
    for schedule in [[2, 2, 2, 1], [1, 2, 0, 2]] {
        let params = SynthParams {
            passes: PassSchedule(schedule),
            ..uniform.clone()
        };
        let v = synth(&a, &params, big, None);
        assert_ne!(v, v2, "{schedule:?} is the uniform solid");
        assert_contained(&v, big, &synth(&a, &params, small, None), small);
        assert_eq!(synth(&a, &params, big, Some(8)), v, "{schedule:?} grouped");
    }
    // A uniform schedule written per level is the same solid.
    let spelled: PassSchedule = "2,2,2,2".parse().unwrap();
    assert_eq!(spelled, PassSchedule::uniform(2));
    assert_eq!(spelled.to_string(), "2");
    assert_eq!(
        "2,2,2,1".parse::<PassSchedule>().unwrap().to_string(),
        "2,2,2,1"
    );
    for bad in ["", "2,2", "2,2,2,2,2", "a", "-1"] {
        assert!(bad.parse::<PassSchedule>().is_err(), "{bad:?} accepted");
    }
}
