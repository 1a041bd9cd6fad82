//! Buffer uploads: what goes up comes back.

use solidsynth::gpu::context::buffers::UPLOAD_PIECE_BYTES;

/// A buffer uploaded in pieces holds every byte, the last piece's padding included (a length
/// neither a whole number of pieces nor of words), and a small one goes up whole.
#[test]
fn buffers_uploaded_in_pieces_hold_their_bytes() {
    let _serial = crate::serial();
    let Some(gpu) = crate::gpu() else { return };
    for len in [10, 2 * UPLOAD_PIECE_BYTES + 4 * 1001 + 3] {
        let bytes: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
        let buffer = gpu.storage_buffer_in_pieces("test upload", &bytes).unwrap();
        let words = gpu.read_words(&buffer, len.div_ceil(4)).unwrap();
        let back: &[u8] = bytemuck::cast_slice(&words);
        assert_eq!(&back[..len], &bytes[..], "{len} bytes");
        assert!(back[len..].iter().all(|&b| b == 0), "{len} bytes: padding");
    }
}
