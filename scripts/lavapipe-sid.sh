#!/usr/bin/env bash
# A newer lavapipe for benchmarks, without touching the system: Debian 12's own Mesa (22.3) runs
# our kernels 2.0-2.4x slower than Mesa 26, whose llvmpipe keeps uniform values scalar (divergence
# analysis, Mesa 25.1) and reads storage buffers with masked gathers instead of a loop with a
# branch per lane. Debian sid's Mesa needs sid's glibc, so this fetches sid's lavapipe with its
# whole dependency closure (glibc and LLVM included: ~70 MB to download, ~330 MB unpacked) into
# target/lavapipe-sid/, and runs a command as a patched copy linked against sid's loader and
# libraries, with that lavapipe as the only Vulkan driver. The command's outputs are the same
# bytes as under any other driver (the kernels are integer-exact).
#
#   scripts/lavapipe-sid.sh fetch              download and unpack (needs Debian's apt, network)
#   scripts/lavapipe-sid.sh run CMD [ARGS...]  run CMD (a dynamically linked binary) under it
#   scripts/lavapipe-sid.sh prepare CMD        only make CMD's patched copy (see below)
#   scripts/lavapipe-sid.sh version            the Mesa version fetched
#
# `run` makes the copy the first time it runs a new build of CMD, with patchelf, which holds the
# whole binary in memory (~240 MB for a release build with its debug info): a peak RSS measured
# around that `run` (GNU time's %M counts the largest process of the tree) is patchelf's, and
# its wall time ~1 s more. `prepare` a new build before measuring it, or that first run's 240 MB
# peak reads as a rare peak of solidsynth's.
#
# sid changes daily and keeps only its latest packages: `fetch` takes whatever is there and
# records the version, so name it with any number measured this way (BENCHMARKS.md does).
# The tests and CI use the system's lavapipe (.ci/run).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)/target/lavapipe-sid"
libs="$root/usr/lib/x86_64-linux-gnu"

fetch() {
    # Unpacked beside the install and moved into place at the end: a failed fetch (network, a
    # package gone from sid) leaves a working install as it was.
    local new="$root.new"
    rm -rf "$new"
    mkdir -p "$new/apt/lists/partial" "$new/apt/cache/archives/partial" "$new/debs"
    echo "deb http://deb.debian.org/debian sid main" > "$new/apt/sources.list"
    local apt_options=(
        -o Dir::Etc::sourcelist="$new/apt/sources.list" -o Dir::Etc::sourceparts=/dev/null
        -o Dir::State::Lists="$new/apt/lists" -o Dir::Cache="$new/apt/cache"
        -o Dir::State::status=/dev/null -o APT::Sandbox::User="$(id -un)"
    )
    apt-get "${apt_options[@]}" -qq update
    # The closure of hard dependencies, real packages only (virtual ones print as <name>).
    local packages
    packages=$(apt-cache "${apt_options[@]}" depends --recurse --no-recommends --no-suggests \
        --no-conflicts --no-breaks --no-replaces --no-enhances mesa-vulkan-drivers libvulkan1 |
        grep -v '^[ <]' | sort -u)
    # patchelf (sid's, run by sid's loader) gives `run` its patched copies.
    packages="$packages patchelf"
    # Package names are single words: split on whitespace on purpose.
    # shellcheck disable=SC2086
    (cd "$new/debs" && apt-get "${apt_options[@]}" -qq download $packages)
    for deb in "$new"/debs/*.deb; do
        dpkg-deb -x "$deb" "$new"
    done
    # Point the ICD manifest's library_path, whatever it holds, at the unpacked driver, and
    # refuse a manifest that would still load another lavapipe.
    local driver="$libs/libvulkan_lvp.so"
    sed -E "s#\"library_path\": *\"[^\"]*\"#\"library_path\": \"$driver\"#" \
        "$new/usr/share/vulkan/icd.d/lvp_icd.json" > "$new/lvp_icd.json"
    grep -q "\"$driver\"" "$new/lvp_icd.json" ||
        { echo "cannot rewrite $new/usr/share/vulkan/icd.d/lvp_icd.json" >&2; exit 1; }
    [ -f "$new/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so" ] ||
        { echo "no libvulkan_lvp.so in sid's mesa-vulkan-drivers" >&2; exit 1; }
    dpkg-deb -f "$new"/debs/mesa-vulkan-drivers_*.deb Version > "$new/VERSION"
    rm -rf "$new/debs" "$new/apt"
    rm -rf "$root"
    mv "$new" "$root"
    echo "lavapipe from Debian sid's Mesa $(cat "$root/VERSION") in $root"
}

case "${1:-}" in
fetch) fetch ;;
version) cat "$root/VERSION" ;;
run | prepare)
    action=$1
    shift
    [ -f "$root/lvp_icd.json" ] || { echo "run '$0 fetch' first" >&2; exit 2; }
    (($#)) || { echo "usage: $0 $action CMD [ARGS...]" >&2; exit 2; }
    cmd="$(realpath "$(command -v "$1")")" || { echo "$1: not found" >&2; exit 2; }
    shift
    # A copy of CMD whose ELF interpreter and library path are sid's, so that it, and any copy of
    # itself it spawns (as `bench` does), starts on sid's glibc; remade when CMD is newer. Named
    # by CMD's path, so target/debug and target/release binaries stay apart. The libraries that
    # lavapipe loads come through LD_LIBRARY_PATH (an RPATH does not reach libraries that carry
    # their own RUNPATH, as LLVM does), so do not let the command start system programs.
    copy="$root/bin/$(echo "$cmd" | md5sum | cut -c1-12)-$(basename "$cmd")"
    if [ ! -e "$copy" ] || [ "$cmd" -nt "$copy" ]; then
        mkdir -p "$root/bin"
        partial="$(mktemp "$copy.XXXXXX")"
        cp "$cmd" "$partial"
        "$libs/ld-linux-x86-64.so.2" --library-path "$libs" "$root/usr/bin/patchelf" \
            --set-interpreter "$libs/ld-linux-x86-64.so.2" --force-rpath --set-rpath "$libs" "$partial"
        chmod +x "$partial"
        mv "$partial" "$copy"
    fi
    [ "$action" = run ] || exit 0
    export VK_ICD_FILENAMES="$root/lvp_icd.json" LD_LIBRARY_PATH="$libs"
    if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
        mkdir -p -m 700 "$root/xdg"
        export XDG_RUNTIME_DIR="$root/xdg"
    fi
    exec "$copy" "$@"
    ;;
*)
    sed -n '2,23p' "$0" | sed 's/^# \{0,1\}//'
    exit 2
    ;;
esac
