//! Properties of the exemplar analysis against brute-force references.

mod common;

use common::{analyze, crop, fixture};
use solidsynth::analysis::coherence::{self, Grid};
use solidsynth::analysis::crossbar::{self, RankedTriple};
use solidsynth::analysis::frame::unpack;
use solidsynth::exemplar::Border;
use solidsynth::io::ssa;

/// With S = every pixel, the strip search is exhaustive, so the kept triples must be exactly the
/// `keep` lowest-CB triples over all (q, r), in (CB, q, r) order: the ranking has no shortcut.
#[test]
fn kept_triples_equal_the_exhaustive_best_when_search_is_complete() {
    let img = crop(&fixture("cells32.png"), 16, 16);
    let strips = crossbar::build_strips(&[&img], Border::Wrap);
    let s = [&strips[0], &strips[0], &strips[0]];
    let n = 256;
    let keep = 100;
    let sets = crossbar::candidates(s, n, keep);
    for p in (0..n).step_by(17) {
        let mut all: Vec<(u32, u32, u32)> = Vec::with_capacity(n * n);
        for q in 0..n {
            for r in 0..n {
                all.push((crossbar::crossbar_error(s, p, q, r), q as u32, r as u32));
            }
        }
        all.sort_unstable();
        let want: Vec<RankedTriple> = all[..keep]
            .iter()
            .map(|&(cb, next1, next2)| RankedTriple { cb, next1, next2 })
            .collect();
        assert_eq!(sets[p], want, "pixel {p}");
    }
}

/// With the default S = 65 (approximate: k-d tree on reduced strips), the kept triples are still
/// near the exhaustive optimum: measured on sampled pixels of a 32x32 exemplar.
#[test]
fn default_search_finds_most_of_the_exhaustive_best() {
    let img = fixture("cells32.png");
    let strips = crossbar::build_strips(&[&img], Border::Wrap);
    let s = [&strips[0], &strips[0], &strips[0]];
    let n = 1024usize;
    let sets = crossbar::candidates(s, 65, 100);
    let (mut best_found, mut recall_sum, mut samples) = (0, 0.0, 0);
    for p in (0..n).step_by(97) {
        // Exact CB of every kept triple, and the kept list is sorted.
        for t in &sets[p] {
            assert_eq!(
                t.cb,
                crossbar::crossbar_error(s, p, t.next1 as usize, t.next2 as usize)
            );
        }
        assert!(sets[p]
            .windows(2)
            .all(|w| (w[0].cb, w[0].next1, w[0].next2) < (w[1].cb, w[1].next1, w[1].next2)));
        let mut all: Vec<u32> = Vec::with_capacity(n * n);
        for q in 0..n {
            for r in 0..n {
                all.push(crossbar::crossbar_error(s, p, q, r));
            }
        }
        all.sort_unstable();
        if sets[p][0].cb == all[0] {
            best_found += 1;
        }
        let threshold = all[99];
        let within = sets[p].iter().filter(|t| t.cb <= threshold).count();
        recall_sum += within as f64 / 100.0;
        samples += 1;
    }
    let recall = recall_sum / samples as f64;
    eprintln!("best found on {best_found}/{samples} pixels, top-100 recall {recall:.2}");
    assert!(
        best_found * 10 >= samples * 9,
        "best triple found on only {best_found}/{samples}"
    );
    assert!(recall >= 0.8, "top-100 recall {recall:.2}");
}

/// Every kept candidate passed the coherence test of the filter's last round, i.e. it is continued
/// by a neighbour's candidate in both other exemplars (checked by a direct scan, not the filter's
/// binary search), and `filter` keeps exactly those, truncated to the lowest CB.
#[test]
fn every_kept_candidate_passes_the_coherence_test() {
    let img = fixture("cells32.png");
    for border in [Border::Wrap, Border::Mirror] {
        let strips = crossbar::build_strips(&[&img], border);
        let s = [&strips[0], &strips[0], &strips[0]];
        let initial = crossbar::candidates(s, 65, 100);
        let g = Grid {
            width: 32,
            height: 32,
        };
        let mut filtered = initial.clone();
        let rounds = coherence::filter(&mut filtered, [g; 3], border, 12, 32);
        // Re-run rounds - 1 rounds without truncation to get the sets the last round tested against.
        let mut before_last = initial.clone();
        if rounds > 1 {
            coherence::filter(&mut before_last, [g; 3], border, usize::MAX, rounds - 1);
        }
        let mut kept = 0;
        for (p, set) in filtered.iter().enumerate() {
            assert!(set.len() <= 12);
            assert!(set.windows(2).all(|w| w[0].cb <= w[1].cb));
            for t in set {
                assert!(
                    coherence::is_coherent(p as u32, t, &before_last, [g; 3], border),
                    "{border:?}: pixel {p} keeps an incoherent triple {t:?}"
                );
                assert!(before_last[p].contains(t));
                kept += 1;
            }
        }
        // The filter removes incoherent triples, it does not just truncate.
        let incoherent_initially = initial
            .iter()
            .enumerate()
            .flat_map(|(p, set)| set.iter().map(move |t| (p, t)))
            .filter(|(p, t)| !coherence::is_coherent(*p as u32, t, &initial, [g; 3], border))
            .count();
        assert!(incoherent_initially > 0);
        assert!(
            kept > 32 * 32 * 4,
            "{border:?}: only {kept} candidates kept"
        );
    }
}

#[test]
fn analysis_is_deterministic_at_any_thread_count() {
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| ssa::to_bytes(&analyze(vec![fixture("marble32.png")], Border::Mirror)))
    };
    let one = run(1);
    assert!(one == run(2), "1 vs 2 threads differ");
    assert!(one == run(3), "1 vs 3 threads differ");
    assert!(one == run(1), "two runs differ");
}

/// One image used for all three axes (computed once, rotated) gives exactly the candidates that
/// three identical images give when each exemplar's set is computed separately.
#[test]
fn three_identical_images_match_the_shared_path() {
    for (name, border) in [
        ("cells32.png", Border::Wrap),
        ("marble32.png", Border::Mirror),
    ] {
        let img = fixture(name);
        let shared = analyze(vec![img.clone()], border);
        let three = analyze(vec![img.clone(), img.clone(), img], border);
        assert!(shared.shared && !three.shared);
        for level in 0..shared.level_count() {
            let pixels = shared.exemplar(0).levels[level].image.pixel_count();
            for a in 0..3 {
                assert_eq!(
                    shared.exemplar(a).levels[level].pca,
                    three.exemplar(a).levels[level].pca
                );
                assert_eq!(
                    shared.exemplar(a).levels[level].candidates_2d,
                    three.exemplar(a).levels[level].candidates_2d
                );
                for p in 0..pixels {
                    assert_eq!(
                        shared.candidates_3d(a, level, p),
                        three.candidates_3d(a, level, p),
                        "{name}: level {level}, exemplar {a}, pixel {p}"
                    );
                    assert_eq!(
                        shared.slab_triple(a, level, p),
                        three.slab_triple(a, level, p)
                    );
                }
            }
        }
    }
}

#[test]
fn candidates_reference_valid_pixels_and_include_self_first_in_2d() {
    let a = analyze(vec![crop(&fixture("cells32.png"), 32, 20)], Border::Mirror);
    for level in 0..a.level_count() {
        let l = &a.exemplar(0).levels[level];
        let (w, h) = (l.image.width, l.image.height);
        let k2 = a.params.k2d[level] as usize;
        for p in 0..(w * h) as usize {
            assert_eq!(
                unpack(l.candidates_2d[p * k2]),
                ((p as u32) % w, (p as u32) / w)
            );
            for t in a.candidates_3d(0, level, p) {
                assert_eq!(unpack(t[0]), ((p as u32) % w, (p as u32) / w));
                for c in t {
                    let (x, y) = unpack(c);
                    assert!(x < w && y < h);
                }
            }
        }
    }
}

#[test]
fn gray_rgba_and_feature_channels_are_analysed() {
    let gray = fixture("stripes32.png");
    assert_eq!(gray.channels, 1);
    let a = analyze(vec![gray.clone()], Border::Wrap);
    assert_eq!(a.color_channels, 1);
    assert_eq!(a.exemplar(0).levels[0].pca.input_dims, 25);

    // Mixed channel counts are unified (gray replicated, alpha added).
    let cells = fixture("cells32.png");
    let mut rgba = solidsynth::exemplar::Image::new(32, 32, 4);
    for (d, s) in rgba
        .pixels
        .chunks_exact_mut(4)
        .zip(cells.pixels.chunks_exact(3))
    {
        d[..3].copy_from_slice(s);
        d[3] = 200;
    }
    let mixed = analyze(vec![gray.clone(), cells.clone(), rgba], Border::Wrap);
    assert_eq!(mixed.color_channels, 4);

    // A feature mask adds one channel.
    let mut mask = solidsynth::exemplar::Image::new(32, 32, 1);
    for (i, m) in mask.pixels.iter_mut().enumerate() {
        *m = if (i % 32) / 8 % 2 == 0 { 255 } else { 0 };
    }
    let input = solidsynth::analysis::AnalysisInput {
        exemplars: vec![cells],
        masks: vec![mask],
        border: Border::Wrap,
        names: vec!["cells".into()],
    };
    let with_feature = solidsynth::lazy::analyze(
        &input,
        &Default::default(),
        &solidsynth::backend::Compute::Cpu,
        &|_, _| {},
    )
    .unwrap();
    assert!(with_feature.has_feature);
    assert_eq!(with_feature.exemplar(0).levels[0].image.channels, 4);
    assert_eq!(with_feature.exemplar(0).levels[0].pca.input_dims, 100);
}
