use super::*;
use crate::gradient::synth::patches::LevelPatches;
use crate::util::hash::SeededRng;

#[test]
fn selection_helpers_equal_a_full_sort() {
    let mut rng = SeededRng::new(7);
    for round in 0..200 {
        let n = 1 + rng.below(300) as usize;
        // Few distinct distances: many ties, broken by the index.
        let pairs: Vec<(u32, u32)> = (0..n)
            .map(|i| (rng.below(1 + round % 20) as u32, i as u32))
            .collect();
        let mut sorted = pairs.clone();
        sorted.sort_unstable();
        let p = 1 + rng.below(n as u64) as usize;
        let mut order: Vec<u64> = pairs
            .iter()
            .map(|&(d, i)| key(f32::from_bits(d), i))
            .collect();
        nearest_first(&mut order, p);
        let order: Vec<(u32, u32)> = order
            .iter()
            .map(|&k| ((k >> 32) as u32, k as u32))
            .collect();
        assert_eq!(order[..p], sorted[..p]);
        let mut rest = order[p..].to_vec();
        rest.sort_unstable();
        assert_eq!(rest, sorted[p..]);
        let k = 1 + rng.below(60) as usize;
        let mut best = KBest::new(k);
        for &(d, i) in &pairs {
            if f32::from_bits(d) <= best.worst() {
                best.offer(key(f32::from_bits(d), i));
            }
        }
        let kept: Vec<(u32, u32)> = best
            .finish()
            .iter()
            .map(|&(d, i)| (d.to_bits(), i))
            .collect();
        assert_eq!(kept, sorted[..k.min(n)]);
    }
}

/// Candidates of a 64x64 crop of the built-in exemplar (3,600 patches of 5x5 samples).
fn level() -> LevelPatches {
    let img = crate::exemplar::default_exemplar().crop(0, 0, 64, 64);
    LevelPatches::build(&img, 1, 5, None, None, 3).unwrap()
}

/// Every candidate's projection, by candidate index.
fn projections(level: &LevelPatches) -> Vec<[f32; KEPT]> {
    (0..level.candidates() as u32)
        .map(|i| *level.point(i))
        .collect()
}

/// The k nearest by brute force, distances summed in the search's order.
fn brute(points: &[[f32; KEPT]], q: &[f32; KEPT], k: usize) -> Vec<(f32, u32)> {
    let mut all: Vec<(u32, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| (distance(q, p).to_bits(), i as u32))
        .collect();
    all.sort_unstable();
    all.truncate(k);
    all.into_iter()
        .map(|(d, i)| (f32::from_bits(d), i))
        .collect()
}

/// Queries near the candidates (a candidate's projection plus noise), as in synthesis.
fn queries(points: &[[f32; KEPT]], n: usize) -> Vec<[f32; KEPT]> {
    let mut rng = SeededRng::new(11);
    (0..n)
        .map(|_| {
            let p = points[rng.below(points.len() as u64) as usize];
            std::array::from_fn(|j| p[j] + (rng.below(2001) as f32 - 1000.0) / 50.0)
        })
        .collect()
}

#[test]
fn every_candidate_is_in_exactly_one_list() {
    let points = projections(&level());
    let index = IvfIndex::build(&points);
    let mut seen = vec![0u32; points.len()];
    for list in &index.lists {
        for bi in list.clone() {
            for &i in &index.lane_candidates[bi] {
                if i != NO_CANDIDATE {
                    seen[i as usize] += 1;
                }
            }
        }
    }
    assert!(seen.iter().all(|&n| n == 1));
    assert_eq!(index.lists.len(), list_count(points.len()));
}

#[test]
fn exact_search_equals_brute_force() {
    let points = projections(&level());
    let index = IvfIndex::build(&points);
    for q in queries(&points, 60) {
        for k in [1, 20, 50] {
            assert_eq!(index.nearest(&q, k, None), brute(&points, &q, k), "k = {k}");
        }
    }
    // Probing every list is the exact search.
    let q = queries(&points, 1)[0];
    let all = Some(index.lists.len());
    assert_eq!(index.nearest(&q, 20, all), index.nearest(&q, 20, None));
}

#[test]
fn approximate_search_finds_most_nearest_patches() {
    let points = projections(&level());
    let index = IvfIndex::build(&points);
    let qs = queries(&points, 400);
    let (mut hits, mut recall) = (0, 0.0);
    for q in &qs {
        let approx = index.nearest(q, 20, Some(8));
        let exact = brute(&points, q, 20);
        // k distinct candidates, nearest first, with their true distances.
        assert_eq!(approx.len(), 20);
        assert!(approx
            .windows(2)
            .all(|w| (w[0].0, w[0].1) < (w[1].0, w[1].1)));
        for &(d, i) in &approx {
            assert_eq!(d, distance(q, &points[i as usize]));
        }
        hits += (approx[0] == exact[0]) as u32;
        recall += approx.iter().filter(|a| exact.contains(a)).count() as f64 / 20.0;
    }
    let (hit_rate, recall) = (hits as f64 / qs.len() as f64, recall / qs.len() as f64);
    assert!(
        hit_rate >= 0.95,
        "nearest found for {hit_rate:.3} of the queries"
    );
    assert!(recall >= 0.9, "recall of the 20 nearest {recall:.3}");
    // Fewer candidates in the probed lists than k: more lists are scanned.
    assert_eq!(index.nearest(&qs[0], 3000, Some(1)).len(), 3000);
}

#[test]
fn partition_groups_separated_points() {
    // Two well-separated groups: each ends in lists of its own group only.
    let points: Vec<[f32; KEPT]> = (0..200)
        .map(|i| {
            let mut p = [0f32; KEPT];
            p[0] = if i % 2 == 0 { 100.0 } else { -100.0 };
            p[1] = (i % 17) as f32;
            p
        })
        .collect();
    let (labels, centres) = partition(&points, 4);
    assert_eq!(centres.len(), 4);
    for (i, p) in points.iter().enumerate() {
        let c = &centres[labels[i] as usize];
        assert_eq!(
            c[0].signum(),
            p[0].signum(),
            "point {i} in the other group's list"
        );
    }
    // Deterministic.
    assert_eq!(partition(&points, 4).0, labels);
}
