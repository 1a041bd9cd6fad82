#!/usr/bin/env bash
# Where lavapipe spends a kernel's time, instruction by instruction. llvmpipe's JIT code has no
# symbols, so `perf report` shows bare addresses: this samples a running solidsynth command
# under scripts/lavapipe-sid.sh with `perf record`, copies the JIT code out of the live process
# with gdb before it exits, disassembles the region holding most samples (during a long
# synthesis, the `correct` variant that runs) and writes it with each instruction's sample count.
# A sample lands on the instruction after the one that stalled, so it also prints the share of
# samples by the preceding instruction's mnemonic (on the 2-core Intel Xeon development machine
# half of `correct`'s samples follow a `vpgatherdd`, BENCHMARKS.md) and the busiest gathers.
#
#   scripts/lavapipe-profile.sh OUTDIR DELAY SECONDS BINARY [ARGS...]
#
# runs `BINARY ARGS` under lavapipe, waits DELAY seconds, samples SECONDS seconds, and writes
# OUTDIR/annotated.txt (count, address, bytes, instruction) and OUTDIR/summary.txt. The command
# must still run when the sampling ends (its code is read from it then): choose a job that
# outlasts DELAY + SECONDS by a few seconds, e.g. `synth --size 256 --backend gpu` with 8 and 5.
# Needs perf, gdb, objdump and python3, and permission to trace the process (root, or
# kernel.perf_event_paranoid <= 1 and ptrace allowed).
set -euo pipefail
cd "$(dirname "$0")/.."
if (($# < 4)); then
    echo "usage: $0 OUTDIR DELAY SECONDS BINARY [ARGS...]" >&2
    exit 2
fi
out=$1 delay=$2 seconds=$3
shift 3
for tool in perf gdb objdump python3; do
    command -v "$tool" >/dev/null || { echo "$0: needs $tool" >&2; exit 2; }
done
mkdir -p "$out"
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
scripts/lavapipe-sid.sh run "$@" >"$out/command.log" 2>&1 &
runner=$!
sleep "$delay"
# lavapipe-sid.sh runs a patched copy of the binary named ...-BASENAME.
pid=$(pgrep -n -f -- "-$(basename "$1") " || true)
if [ -z "$pid" ]; then
    echo "$0: the command is not running after $delay s (see $out/command.log)" >&2
    exit 1
fi
perf record -q -F 999 -p "$pid" -o "$out/perf.data" -- sleep "$seconds" 2>/dev/null
# The JIT code: the process's anonymous executable mappings, copied while it still runs.
awk '$2 ~ /x/ && $6 == "" {print $1}' "/proc/$pid/maps" >"$out/regions.txt"
while read -r region; do
    gdb -p "$pid" -batch -ex "dump binary memory $out/jit_${region%-*}.bin 0x${region%-*} 0x${region#*-}" \
        >/dev/null 2>&1 || true
done <"$out/regions.txt"
wait "$runner" || true
perf script -i "$out/perf.data" -F ip 2>/dev/null | sort | uniq -c >"$out/ips.txt"
OUT="$out" python3 - <<'EOF'
import collections, os, re, subprocess

out = os.environ["OUT"]
samples = collections.Counter()
for line in open(f"{out}/ips.txt"):
    count, ip = line.split()
    samples[int(ip, 16)] += int(count)
regions = []
for line in open(f"{out}/regions.txt"):
    lo, hi = (int(v, 16) for v in line.split("-"))
    if os.path.exists(f"{out}/jit_{lo:x}.bin"):
        regions.append((lo, hi))
in_region = collections.Counter()
for ip, count in samples.items():
    for lo, hi in regions:
        if lo <= ip < hi:
            in_region[(lo, hi)] += count
total = sum(samples.values())
if not in_region:
    raise SystemExit("no samples in the JIT code: sample later, or a longer job")
(lo, hi), jit = in_region.most_common(1)[0]
listing = subprocess.run(
    ["objdump", "-D", "-b", "binary", "-mi386:x86-64", f"--adjust-vma={lo:#x}", f"{out}/jit_{lo:x}.bin"],
    capture_output=True, text=True, check=True).stdout
code = []
for line in listing.splitlines():
    m = re.match(r"\s*([0-9a-f]+):\t(.*)", line)
    if m:
        code.append((int(m.group(1), 16), m.group(2)))
with open(f"{out}/annotated.txt", "w") as f:
    for address, text in code:
        f.write(f"{samples.get(address, 0):7d} {address:x}: {text}\n")

def mnemonic(text):
    fields = text.split("\t")
    return fields[-1].split()[0] if len(fields) > 1 and fields[-1].split() else "?"

after = collections.Counter()
gathers = []
for i in range(1, len(code)):
    count = samples.get(code[i][0], 0)
    after[mnemonic(code[i - 1][1])] += count
    if "gather" in code[i - 1][1]:
        gathers.append((count, code[i - 1][0], code[i - 1][1].split("\t")[-1]))
with open(f"{out}/summary.txt", "w") as f:
    f.write(f"{total} samples; {jit} ({100 * jit / total:.1f}%) in the JIT region "
            f"{lo:#x}-{hi:#x} ({hi - lo} bytes), annotated in annotated.txt\n\n")
    f.write("samples by the instruction before (where the stall was):\n")
    for name, count in after.most_common(15):
        f.write(f"{count:7d} {100 * count / jit:5.1f}%  {name}\n")
    f.write(f"\nthe busiest of its {len(gathers)} gathers (samples just after each):\n")
    for count, address, text in sorted(gathers, reverse=True)[:15]:
        f.write(f"{count:7d} {address:x}: {text}\n")
print(open(f"{out}/summary.txt").read())
EOF
