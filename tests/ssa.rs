//! The .ssa format: round trip, rejection of damaged files, and a seeded fuzz of the parser.

mod common;

use common::{analyze, fixture};
use solidsynth::exemplar::Border;
use solidsynth::io::ssa;
use solidsynth::util::hash::SeededRng;

fn sample() -> Vec<u8> {
    ssa::to_bytes(&analyze(vec![fixture("marble32.png")], Border::Mirror))
}

#[test]
fn round_trip_is_lossless_and_byte_identical() {
    let a = analyze(vec![fixture("cells32.png")], Border::Wrap);
    let bytes = ssa::to_bytes(&a);
    let back = ssa::from_bytes(&bytes).unwrap();
    assert_eq!(a, back);
    assert!(ssa::to_bytes(&back) == bytes);
    let three = analyze(
        vec![
            fixture("cells32.png"),
            fixture("marble32.png"),
            fixture("cells32.png"),
        ],
        Border::Mirror,
    );
    assert_eq!(ssa::from_bytes(&ssa::to_bytes(&three)).unwrap(), three);
}

#[test]
fn wrong_magic_version_checksum_and_truncation_are_named() {
    let good = sample();
    let mut bad = good.clone();
    bad[0] = b'X';
    assert!(ssa::from_bytes(&bad).unwrap_err().contains("magic"));
    let mut bad = good.clone();
    bad[8] = 99;
    assert!(ssa::from_bytes(&bad).unwrap_err().contains("version 99"));
    let mut bad = good.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x40;
    assert!(ssa::from_bytes(&bad).unwrap_err().contains("checksum"));
    assert!(ssa::from_bytes(&good[..good.len() - 5])
        .unwrap_err()
        .contains("truncated"));
    assert!(ssa::from_bytes(&good[..10])
        .unwrap_err()
        .contains("too short"));
    assert!(ssa::from_bytes(&[]).is_err());
}

/// The correction scores a 3D candidate's own coordinate once per list, so a list holding a
/// triple without its pixel must be refused, not synthesized from.
#[test]
fn a_3d_candidate_without_its_own_pixel_is_refused() {
    let mut a = analyze(vec![fixture("marble32.png")], Border::Mirror);
    let level = &mut a.exemplars[0].levels[0];
    let p = level
        .counts_3d
        .iter()
        .position(|&c| c > 0)
        .expect("a pixel with candidates");
    let k = a.params.max_3d as usize;
    let t = &mut level.candidates_3d[p * k];
    t[0] = if t[0] == 0 { 1 } else { 0 };
    let err = ssa::from_bytes(&ssa::to_bytes(&a)).unwrap_err();
    assert!(err.contains("does not contain it"), "{err}");
}

/// Mutations behind a valid checksum reach the structural checks: they must return errors (or a
/// valid analysis), never panic or allocate absurdly.
#[test]
fn fuzz_parser_with_mutated_payloads() {
    let good = sample();
    let payload = &good[32..];
    let mut rng = SeededRng::new(2026);
    let mut rejected = 0;
    for i in 0..3000 {
        let mut p = payload.to_vec();
        match i % 4 {
            0 => {
                for _ in 0..1 + rng.below(4) {
                    let at = rng.below(p.len() as u64) as usize;
                    p[at] = rng.below(256) as u8;
                }
            }
            1 => {
                // Corrupt a header-ish word near the start with an extreme value.
                let at = (rng.below(64) as usize) * 4;
                let v = [0u32, 1, 2, 3, 0xFFFF, 0xFFFF_FFFF, 0x8000_0000][rng.below(7) as usize];
                if at + 4 <= p.len() {
                    p[at..at + 4].copy_from_slice(&v.to_le_bytes());
                }
            }
            2 => p.truncate(rng.below(p.len() as u64) as usize),
            _ => {
                let at = rng.below(p.len() as u64) as usize;
                p.insert(at, rng.below(256) as u8);
            }
        }
        if ssa::parse_payload(&p).is_err() {
            rejected += 1;
        }
    }
    assert!(
        rejected > 1000,
        "only {rejected} of 3000 mutations rejected"
    );
}

#[test]
fn fuzz_whole_file_bytes() {
    let good = sample();
    let mut rng = SeededRng::new(9);
    for _ in 0..2000 {
        let mut b = good.clone();
        let at = rng.below(b.len() as u64) as usize;
        b[at] ^= 1 << rng.below(8);
        assert!(
            ssa::from_bytes(&b).is_err(),
            "a flipped bit at {at} was accepted"
        );
    }
}
