//! Process memory: readings for benchmark reports, and handing freed memory back.

/// Peak resident set size of this process in bytes (Linux `VmHWM`), if known.
#[cfg(any(feature = "cli", feature = "internals"))]
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
/// same time, on the 2-core Intel Xeon development machine; the CPU backend's times and memory
/// did not move (BENCHMARKS.md). Call it first thing in `main`, before any thread exists. A no-op
/// off glibc.
#[cfg(any(feature = "cli", feature = "internals"))]
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

/// The memory a request may plan to use: the least of the machine's available memory
/// (`MemAvailable` of /proc/meminfo), the room left under this process's cgroup memory limits
/// (v2 `memory.max - memory.current`, v1 `memory.limit_in_bytes - memory.usage_in_bytes`, this
/// cgroup's and its ancestors': a container's or a CI runner's limit, which the kernel enforces
/// by killing the process), the room left in its address-space limit (`ulimit -v`, where
/// allocations fail and the process aborts) and `SOLIDSYNTH_MEMORY_BUDGET_MIB` when that is
/// set. u64::MAX when none is known.
pub fn available_memory() -> u64 {
    available_memory_under(std::path::Path::new("/"))
        .min(address_space_room())
        .min(budget().unwrap_or(u64::MAX))
}

/// The variable that sets a memory budget of its own (in MiB).
const BUDGET: &str = "SOLIDSYNTH_MEMORY_BUDGET_MIB";

/// The budget `SOLIDSYNTH_MEMORY_BUDGET_MIB` sets, in bytes; None when unset or unreadable
/// (warned about once).
fn budget() -> Option<u64> {
    let v = std::env::var(BUDGET).ok()?;
    match v.trim().parse::<u64>() {
        Ok(mib) => Some(mib.saturating_mul(1 << 20)),
        Err(_) => {
            static WARNED: std::sync::Once = std::sync::Once::new();
            WARNED.call_once(|| {
                tracing::warn!("{BUDGET}={v} ignored: not a whole number of MiB");
            });
            None
        }
    }
}

/// A byte count for a message, in the largest binary unit it fills at least once: "18.9 GiB",
/// "350.0 MiB", "0 bytes".
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 4] = ["KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = None;
    for name in UNITS {
        if value < 1024.0 {
            break;
        }
        value /= 1024.0;
        unit = Some(name);
    }
    match unit {
        Some(name) => format!("{value:.1} {name}"),
        None => format!("{bytes} bytes"),
    }
}

/// "N is available" for a refusal of `available` bytes (what [`available_memory`] gave), naming
/// `SOLIDSYNTH_MEMORY_BUDGET_MIB` when that budget is what limits it.
pub fn available_text(available: u64) -> String {
    let set_by_budget = budget() == Some(available);
    let mut text = format!("{} is available", human_bytes(available));
    if set_by_budget {
        text.push_str(&format!(" under {BUDGET}={}", available >> 20));
    }
    text
}

/// The room left under this process's address-space limit (`RLIMIT_AS`, `ulimit -v`): the limit
/// less its virtual size now (`VmSize` of /proc/self/status). u64::MAX without a limit.
fn address_space_room() -> u64 {
    #[cfg(target_os = "linux")]
    {
        let mut limit = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes the limit into the struct it is given.
        if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut limit) } != 0
            || limit.rlim_cur == libc::RLIM_INFINITY
        {
            return u64::MAX;
        }
        let used = std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| {
                let line = s.lines().find(|l| l.starts_with("VmSize:"))?.to_string();
                line.split_whitespace().nth(1)?.parse::<u64>().ok()
            })
            .map_or(0, |kib| kib.saturating_mul(1024));
        // (rlim_t is u64 here, narrower on some 32-bit targets.)
        #[allow(clippy::unnecessary_cast)]
        let limit = limit.rlim_cur as u64;
        limit.saturating_sub(used)
    }
    #[cfg(not(target_os = "linux"))]
    {
        u64::MAX
    }
}

/// [`available_memory`] without the override, reading `/proc` and `/sys/fs/cgroup` under `root`
/// (a fake tree in tests).
pub fn available_memory_under(root: &std::path::Path) -> u64 {
    let read = |p: &str| std::fs::read_to_string(root.join(p)).ok();
    let machine = read("proc/meminfo")
        .and_then(|s| {
            let line = s
                .lines()
                .find(|l| l.starts_with("MemAvailable:"))?
                .to_string();
            line.split_whitespace().nth(1)?.parse::<u64>().ok()
        })
        .map_or(u64::MAX, |kib| kib.saturating_mul(1024));
    let cgroups = read("proc/self/cgroup").unwrap_or_default();
    machine.min(cgroup_room(root, &cgroups))
}

/// The least room under the memory limits of the cgroups named in `/proc/self/cgroup`'s text,
/// up their hierarchy to the root; u64::MAX where none is set.
fn cgroup_room(root: &std::path::Path, proc_cgroup: &str) -> u64 {
    let number = |path: std::path::PathBuf| -> Option<u64> {
        std::fs::read_to_string(path)
            .ok()?
            .trim()
            .parse::<u64>()
            .ok()
    };
    let mut room = u64::MAX;
    for line in proc_cgroup.lines() {
        let mut fields = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) =
            (fields.next(), fields.next(), fields.next())
        else {
            continue;
        };
        let (base, limit_file, usage_file) = if controllers.is_empty() {
            // cgroup v2: one unified hierarchy.
            ("sys/fs/cgroup", "memory.max", "memory.current")
        } else if controllers.split(',').any(|c| c == "memory") {
            (
                "sys/fs/cgroup/memory",
                "memory.limit_in_bytes",
                "memory.usage_in_bytes",
            )
        } else {
            continue;
        };
        // This cgroup and its ancestors (a limit anywhere above applies too).
        let mut dir = std::path::PathBuf::from(path.trim_start_matches('/'));
        loop {
            let at = root.join(base).join(&dir);
            // "max" (v2) or a huge number (v1: no limit) parse as none / stay above the room.
            if let (Some(limit), Some(usage)) =
                (number(at.join(limit_file)), number(at.join(usage_file)))
            {
                room = room.min(limit.saturating_sub(usage));
            }
            if !dir.pop() {
                break;
            }
        }
    }
    room
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree(files: &[(&str, &str)]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for (path, text) in files {
            let p = dir.path().join(path);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, text).unwrap();
        }
        dir
    }

    const MEMINFO: &str = "MemTotal: 16000000 kB\nMemAvailable: 8000000 kB\n";

    #[test]
    fn byte_counts_read_in_the_unit_they_fill() {
        assert_eq!(human_bytes(0), "0 bytes");
        assert_eq!(human_bytes(1023), "1023 bytes");
        assert_eq!(human_bytes(1536), "1.5 KiB");
        assert_eq!(human_bytes(350 << 20), "350.0 MiB");
        assert_eq!(human_bytes(19 << 30), "19.0 GiB");
        assert_eq!(human_bytes(3 << 40), "3.0 TiB");
    }

    /// A container's cgroup limit is the budget when it is tighter than the machine's memory:
    /// v2 (the cgroup's own and an ancestor's), v1, and none.
    #[test]
    fn the_budget_reads_cgroup_limits() {
        let machine = 8_000_000 * 1024;
        let none = tree(&[("proc/meminfo", MEMINFO), ("proc/self/cgroup", "0::/\n")]);
        assert_eq!(available_memory_under(none.path()), machine);
        let v2 = tree(&[
            ("proc/meminfo", MEMINFO),
            ("proc/self/cgroup", "0::/ci/job\n"),
            ("sys/fs/cgroup/ci/job/memory.max", "max\n"),
            ("sys/fs/cgroup/ci/job/memory.current", "100\n"),
            ("sys/fs/cgroup/ci/memory.max", "1073741824\n"),
            ("sys/fs/cgroup/ci/memory.current", "73741824\n"),
        ]);
        assert_eq!(available_memory_under(v2.path()), 1_000_000_000);
        let v1 = tree(&[
            ("proc/meminfo", MEMINFO),
            (
                "proc/self/cgroup",
                "12:cpu,cpuacct:/x\n4:memory:/docker/abc\n",
            ),
            (
                "sys/fs/cgroup/memory/docker/abc/memory.limit_in_bytes",
                "536870912\n",
            ),
            (
                "sys/fs/cgroup/memory/docker/abc/memory.usage_in_bytes",
                "36870912\n",
            ),
            (
                "sys/fs/cgroup/memory/memory.limit_in_bytes",
                "9223372036854771712\n",
            ),
            ("sys/fs/cgroup/memory/memory.usage_in_bytes", "5000000000\n"),
        ]);
        assert_eq!(available_memory_under(v1.path()), 500_000_000);
        // Over its limit already: no room.
        let full = tree(&[
            ("proc/meminfo", MEMINFO),
            ("proc/self/cgroup", "0::/\n"),
            ("sys/fs/cgroup/memory.max", "1000\n"),
            ("sys/fs/cgroup/memory.current", "2000\n"),
        ]);
        assert_eq!(available_memory_under(full.path()), 0);
        let nothing = tempfile::tempdir().unwrap();
        assert_eq!(available_memory_under(nothing.path()), u64::MAX);
    }
}
