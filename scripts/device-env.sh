# Sourced by the scripts/device-*.sh scripts on the device tool's GPU machine: the Vulkan loader
# from the carried .debs where the image has none (device README), NVIDIA's ICD when it is
# there, the directories solidsynth needs, and $out, the results' directory ($OUT or ./out).
if [[ -d .gl ]] && ! ldconfig -p | grep -q libvulkan.so.1; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
nvidia_icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [[ -f $nvidia_icd && -z "${VK_DRIVER_FILES:-}" ]]; then
    export VK_DRIVER_FILES=$nvidia_icd
fi
export SOLIDSYNTH_CACHE_DIR=${SOLIDSYNTH_CACHE_DIR:-/tmp/solidsynth-cache}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/xdg}
mkdir -p "$XDG_RUNTIME_DIR"
out=${OUT:-out}
mkdir -p "$out"
