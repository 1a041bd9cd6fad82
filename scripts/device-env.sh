# Sourced by scripts/device-bench.sh and scripts/device-profile.sh on the device tool's GPU
# machine: the Vulkan loader from the carried .debs where the image has none (device README),
# NVIDIA's ICD when it is there, and the directories solidsynth needs.
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
