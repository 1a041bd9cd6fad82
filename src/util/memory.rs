//! Process memory: readings for benchmark reports, and handing freed memory back.

/// Peak resident set size of this process in bytes (Linux `VmHWM`), if known.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Hand the heap's free pages back to the system when the heap holds over 16 MiB of free
/// memory. glibc keeps memory freed by other threads in their arenas (lavapipe's shader
/// compiler, rayon's workers) and returns the main arena's only above a threshold; between a
/// request's groups about 20 MB of the bunny's surface bake on lavapipe was such free memory,
/// resident for the rest of the run. Below the threshold the free memory is mostly the churn of
/// one group, which the next one reuses: trimming it after every group made the bunny's bake
/// 13% slower on the CPU backend, faulting the same pages in again. A no-op off glibc.
pub fn return_free_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallinfo only reads the allocator's counters (all arenas), and malloc_trim only
    // releases free memory; no pointer the program holds changes. (mallinfo, not mallinfo2,
    // which needs glibc 2.33: its int counters wrap past 2 GiB, read here as u32 up to 4 GiB,
    // and a wrapped count only skips one trim.)
    unsafe {
        if libc::mallinfo().fordblks as u32 > 16 << 20 {
            libc::malloc_trim(0);
        }
    }
}

/// glibc arenas for the whole process: 2 unless the user chose (`MALLOC_ARENA_MAX`, or
/// `GLIBC_TUNABLES` naming `arena_max`). glibc gives threads up to 8 arenas per core, and memory
/// a thread frees stays in its arena: lavapipe's queue and compiler threads, wgpu's and rayon's
/// workers each kept some resident. With 2, the bunny at 1024 on lavapipe (fast flags) peaked at
/// 185-186 MB instead of 191-194 and `synth --size 256` at 385-391 MB instead of 393, in the
/// same time; the CPU backend's times and memory did not move (BENCHMARKS.md, session 37). Call it
/// first thing in `main`, before any thread exists. A no-op off glibc.
pub fn limit_heap_arenas() {
    let chosen = std::env::var_os("MALLOC_ARENA_MAX").is_some()
        || std::env::var("GLIBC_TUNABLES").is_ok_and(|t| t.contains("arena_max"));
    if chosen {
        return;
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; called before other threads exist.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 2);
    }
}

/// The memory a request may plan to use: MemAvailable from /proc/meminfo (u64::MAX when
/// unknown), capped by `SOLIDSYNTH_MEMORY_BUDGET_MIB` when that is set.
pub fn available_memory() -> u64 {
    let available = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            let line = s
                .lines()
                .find(|l| l.starts_with("MemAvailable:"))?
                .to_string();
            line.split_whitespace().nth(1)?.parse::<u64>().ok()
        })
        .map_or(u64::MAX, |kib| kib * 1024);
    let budget = std::env::var("SOLIDSYNTH_MEMORY_BUDGET_MIB")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .map_or(u64::MAX, |mib| mib.saturating_mul(1 << 20));
    available.min(budget)
}
