//! The .ptm format: byte-identical round trips, the payload's layout, damaged files named, a seeded fuzz of the reader.

use super::*;

#[test]
fn ptm_files_round_trip_byte_identical() {
    for format in [PtmFormat::Lrgb, PtmFormat::Rgb] {
        let ptm = source(24, format, 1);
        let bytes = format::to_bytes(&ptm);
        let back = format::from_bytes(&bytes).unwrap();
        assert_eq!(back, ptm);
        assert_eq!(format::to_bytes(&back), bytes);
        let text = String::from_utf8_lossy(&bytes[..40]).to_string();
        assert!(
            text.starts_with(&format!("PTM_1.2\n{}\n24\n24\n", format.header_name())),
            "{text}"
        );
    }
}

#[test]
fn ptm_payload_runs_bottom_to_top_in_blocks() {
    // A 2x2 LRGB map with distinct bytes: the file holds the bottom row first, coefficients of
    // all pixels, then colours of all pixels.
    let texels: Vec<u8> = (0..4u8)
        .flat_map(|p| (0..9u8).map(move |k| p * 10 + k))
        .collect();
    let ptm = Ptm {
        format: PtmFormat::Lrgb,
        width: 2,
        height: 2,
        scale: [1.0; 6],
        bias: [0; 6],
        texels,
    };
    let bytes = format::to_bytes(&ptm);
    let payload = &bytes[bytes.len() - 36..];
    assert_eq!(&payload[..6], &[20, 21, 22, 23, 24, 25]); // pixel (0, 1): bottom-left
    assert_eq!(&payload[24..27], &[26, 27, 28]);
    let rgb = Ptm {
        format: PtmFormat::Rgb,
        width: 1,
        height: 2,
        scale: [0.5; 6],
        bias: [3; 6],
        texels: (0..36).collect(),
    };
    let bytes = format::to_bytes(&rgb);
    let payload = &bytes[bytes.len() - 36..];
    assert_eq!(&payload[..6], &[18, 19, 20, 21, 22, 23]); // red plane, bottom pixel
    assert_eq!(&payload[6..12], &[0, 1, 2, 3, 4, 5]); // red plane, top pixel
    assert_eq!(&payload[12..18], &[24, 25, 26, 27, 28, 29]); // green plane, bottom pixel
    assert_eq!(format::from_bytes(&bytes).unwrap(), rgb);
}

#[test]
fn damaged_ptm_files_are_named() {
    let good = format::to_bytes(&source(16, PtmFormat::Lrgb, 2));
    assert!(format::from_bytes(b"PTM_1.1\nPTM_FORMAT_LRGB\n")
        .unwrap_err()
        .contains("PTM_1.2"));
    let mut bad = good.clone();
    bad[12] = b'X';
    assert!(format::from_bytes(&bad)
        .unwrap_err()
        .contains("unsupported PTM format"));
    assert!(format::from_bytes(&good[..good.len() - 1])
        .unwrap_err()
        .contains("truncated"));
    assert!(format::from_bytes(&good[..30])
        .unwrap_err()
        .contains("truncated"));
    let mut long = good.clone();
    long.push(0);
    assert!(format::from_bytes(&long)
        .unwrap_err()
        .contains("unexpected bytes"));
    assert!(format::from_bytes(&[]).is_err());
    let huge = b"PTM_1.2\nPTM_FORMAT_RGB\n99999 99999\n1 1 1 1 1 1\n0 0 0 0 0 0\n";
    assert!(format::from_bytes(huge)
        .unwrap_err()
        .contains("out of range"));
    // Past u32 too: out of range, not "not a whole number".
    let past = b"PTM_1.2\nPTM_FORMAT_RGB\n99999999999 9\n1 1 1 1 1 1\n0 0 0 0 0 0\n";
    let e = format::from_bytes(past).unwrap_err();
    assert!(e.contains("width 99999999999 is out of range"), "{e}");
}

/// Truncations, bit flips and header mutations in a loop: errors, never panics.
#[test]
fn fuzz_ptm_reader() {
    let good = [
        format::to_bytes(&source(12, PtmFormat::Lrgb, 4)),
        format::to_bytes(&source(12, PtmFormat::Rgb, 4)),
    ];
    let mut rng = SeededRng::new(2026);
    let (mut rejected, mut accepted) = (0, 0);
    for i in 0..4000 {
        let mut b = good[i % 2].clone();
        let header = b.iter().position(|&c| c == b'\n').unwrap() + 80;
        match i % 5 {
            0 => b.truncate(rng.below(b.len() as u64) as usize),
            1 => {
                for _ in 0..1 + rng.below(4) {
                    let at = rng.below(header.min(b.len()) as u64) as usize;
                    b[at] ^= 1 << rng.below(8);
                }
            }
            2 => {
                let at = rng.below(header.min(b.len()) as u64) as usize;
                b[at] = b"0123456789 -.\n\reE+x"[rng.below(19) as usize];
            }
            3 => {
                let at = rng.below(b.len() as u64) as usize;
                b[at] = rng.below(256) as u8; // payload bytes: any value is a valid texel
            }
            _ => {
                let at = rng.below(header.min(b.len()) as u64) as usize;
                b.insert(at, b"9 \n-"[rng.below(4) as usize]);
            }
        }
        match std::panic::catch_unwind(|| format::from_bytes(&b)) {
            Ok(Ok(p)) => {
                accepted += 1;
                assert_eq!(p.texels.len(), p.pixels() * p.format.texel_bytes());
            }
            Ok(Err(_)) => rejected += 1,
            Err(_) => panic!("reader panicked on mutation {i}"),
        }
    }
    assert!(
        rejected > 1000 && accepted > 100,
        "rejected {rejected}, accepted {accepted}"
    );
}
