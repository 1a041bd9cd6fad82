#!/usr/bin/env bash
# Where a command's time goes on the device tool's lent GPU machine, which has no perf but has
# cuda-gdb: the main thread's stack sampled with cuda-gdb while the command runs, and the
# debug timings it logs with SOLIDSYNTH_LOG=solidsynth=debug (read-backs, brick indices, plans)
# summed in a second, unsampled run. It shows host-side costs that per-kernel GPU timings miss,
# such as the volume and cut targets of BENCHMARKS.md on an NVIDIA H100.
#
# Prepare on the build machine (keeps the symbols, drops the debug info; about 17 MB):
#   scripts/device-profile.sh --prepare
# then on the GPU machine, from the repository root (dist/ and .gl carried):
#   scripts/device-profile.sh NAME SAMPLES SOLIDSYNTH-ARGS...
#   e.g. scripts/device-profile.sh synth512 40 synth --size 512 --backend gpu -o /tmp/v.nrrd
# Writes $OUT/NAME.stacks (raw samples), $OUT/NAME.log (the timed run's debug log) and
# $OUT/NAME.txt (both summaries), and prints the summaries. Attaching pauses the process, so
# the sampled run is slower; its time is not the command's.
set -uo pipefail
cd "$(dirname "$0")/.."

if [[ "${1:-}" == "--prepare" ]]; then
    set -e
    cargo build --release --locked
    mkdir -p dist
    strip --strip-debug -o dist/solidsynth-sym target/release/solidsynth
    ls -la dist/solidsynth-sym
    exit 0
fi
if (($# < 3)); then
    echo "usage: $0 --prepare | NAME SAMPLES SOLIDSYNTH-ARGS..." >&2
    exit 2
fi
name=$1
samples=$2
shift 2
# shellcheck source=scripts/device-env.sh
source scripts/device-env.sh
ss=dist/solidsynth-sym
command -v cuda-gdb >/dev/null || echo "no cuda-gdb: stacks not sampled" >&2

# Timed run with debug timings (also warms the analysis cache and the driver's shader cache).
SOLIDSYNTH_LOG=solidsynth=debug "$ss" "$@" >"$out/$name.log" 2>&1

# Sampled run.
: >"$out/$name.stacks"
"$ss" --quiet "$@" >/dev/null 2>&1 &
pid=$!
sleep 0.3
n=0
while kill -0 "$pid" 2>/dev/null && ((n < samples)) && command -v cuda-gdb >/dev/null; do
    echo "=== sample $n" >>"$out/$name.stacks"
    timeout 20 cuda-gdb -q -batch -p "$pid" -ex "thread 1" -ex "bt 40" >>"$out/$name.stacks" 2>&1
    n=$((n + 1))
done
kill "$pid" 2>/dev/null
wait "$pid" 2>/dev/null

python3 - "$out/$name.stacks" "$out/$name.log" <<'PY' | tee "$out/$name.txt"
import collections, re, sys

stacks, log = sys.argv[1], sys.argv[2]
samples = [s for s in open(stacks).read().split("=== sample")[1:] if "#0 " in s]
inclusive, leaf = collections.Counter(), collections.Counter()
for s in samples:
    names = []
    for line in s.splitlines():
        m = re.match(r"#\d+\s+(?:0x[0-9a-f]+ in )?(\S+) \(", line)
        if m:
            names.append(m.group(1))
    own = next((n for n in names if "solidsynth" in n), "?")
    leaf[(names[0][:40] if names else "?", own[:80])] += 1
    for n in set(names):
        if "solidsynth" in n or "wgpu" in n:
            inclusive[n[:100]] += 1
print(f"{len(samples)} stack samples of the main thread")
print("-- innermost frame, innermost solidsynth frame")
for (a, b), c in leaf.most_common(15):
    print(f"{c:5}  {a}  <  {b}")
print("-- functions on the stack (share of samples)")
for n, c in inclusive.most_common(30):
    print(f"{100 * c / max(1, len(samples)):5.0f}%  {n}")
total, count = collections.defaultdict(float), collections.Counter()
text = re.sub(r"\x1b\[[0-9;]*m", "", open(log).read())
for line in text.splitlines():
    m = re.search(r"read back ([\d.]+) MiB: queued work and copy ([\d.]+) ms, map ([\d.]+) ms, to host ([\d.]+) ms", line)
    if m:
        for key, v in zip(["MiB read back", "waiting for the GPU (and the copy)", "mapping", "copying to the host"], m.groups()):
            total[key] += float(v)
            count[key] += 1
        continue
    m = re.search(r"DEBUG (.*?) in ([\d.]+) ms", line) or re.search(r"DEBUG (.*?): ([\d.]+) ms", line)
    if m:
        key = re.sub(r"\d+", "N", m.group(1))
        total[key] += float(m.group(2))
        count[key] += 1
print("-- debug timings of the unsampled run (ms, or MiB; how many)")
for k, v in sorted(total.items(), key=lambda kv: -kv[1]):
    print(f"{v:10.1f}  {k} ({count[k]})")
for line in text.splitlines()[-3:]:
    print(line)
PY
