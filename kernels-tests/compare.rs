//! The comparator of GPU and CPU outputs, and the proof that it can fail.

/// Bit-exact comparison of two word buffers; the error names the first difference.
pub fn words_equal(what: &str, cpu: &[u32], gpu: &[u32]) -> Result<(), String> {
    if cpu.len() != gpu.len() {
        return Err(format!(
            "{what}: length {} (CPU) vs {} (GPU)",
            cpu.len(),
            gpu.len()
        ));
    }
    let diffs = cpu.iter().zip(gpu).filter(|(a, b)| a != b).count();
    match cpu.iter().zip(gpu).position(|(a, b)| a != b) {
        None => Ok(()),
        Some(i) => Err(format!(
            "{what}: {diffs} of {} words differ; first at {i}: CPU {:#010x} vs GPU {:#010x}",
            cpu.len(),
            cpu[i],
            gpu[i]
        )),
    }
}

#[test]
fn comparator_rejects_a_perturbed_buffer() {
    let _serial = crate::serial();
    let cpu: Vec<u32> = (0..1000u32).map(|i| i.wrapping_mul(2654435761)).collect();
    assert!(words_equal("same", &cpu, &cpu.clone()).is_ok());
    for (index, bit) in [(0usize, 0u32), (517, 13), (999, 31)] {
        let mut perturbed = cpu.clone();
        perturbed[index] ^= 1 << bit;
        let err = words_equal("perturbed", &cpu, &perturbed).unwrap_err();
        assert!(err.contains(&format!("first at {index}")), "{err}");
    }
    assert!(words_equal("short", &cpu, &cpu[..999]).is_err());
}
