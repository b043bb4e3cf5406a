#!/usr/bin/env bash
# The GPU check for a machine with a GPU and no package registry (a lent data-centre GPU):
# runs `vesalius verify --compute gpu`, the GPU lines of `vesalius bench` for the procedures
# that have a compute path (the kernel alone, then the procedure with its models on the
# device over the demo's first 2 s) and every procedure's stereo frame (and those with a GPU
# path again on one device shared by frames and steps), and prints one JSON
# summary of every line, then the issue's targets against them (`scripts/gpu-targets.py`;
# GPU_PEAK_GBS gives the card's bandwidth where its name is not in the script's table).
# Nothing is compiled here.
#
#   scripts/gpu-check.sh [BINARY]     (default: target/release/vesalius)
#
# Files go to $GPU_CHECK_OUT (default /tmp/gpu-check); the summary is printed last.
# Carry a stripped release binary built elsewhere and, where the machine has no Vulkan
# loader, the loader's .deb files in .gl/ (README, "GPU"): they are unpacked first.
set -uo pipefail
bin=${1:-target/release/vesalius}
out=${GPU_CHECK_OUT:-/tmp/gpu-check}
mkdir -p "$out"
# The Vulkan loader and the GL dispatch libraries the NVIDIA driver's Vulkan part needs
# (libglvnd), carried as .deb files where the machine lacks them.
for f in .gl/*.deb; do
    [ -e "$f" ] && dpkg -x "$f" /
done
ldconfig
# The NVIDIA driver's Vulkan manifest, where the loader does not find it by itself.
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -z "${VK_DRIVER_FILES:-}" ] && [ -e "$icd" ]; then
    export VK_DRIVER_FILES=$icd
fi
if command -v nvidia-smi >/dev/null; then
    nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm,clocks.max.mem --format=csv,noheader \
        | tee "$out/gpu.txt"
fi
status=0
echo "== vesalius verify --compute gpu" >&2
if ! "$bin" verify --compute gpu --json >"$out/verify-gpu.jsonl" 2>"$out/verify-gpu.err"; then
    status=1
    cat "$out/verify-gpu.err" >&2
fi
for p in rectum cholecystectomy; do
    echo "== vesalius bench $p --compute gpu" >&2
    if ! "$bin" bench "$p" --compute gpu --json >"$out/$p-gpu.jsonl" 2>"$out/$p-gpu.err"; then
        status=1
        cat "$out/$p-gpu.err" >&2
    fi
done
# Every procedure's stereo frame at the Vive's 1080 x 1200 a eye: alone, then for 3 s at 90 Hz
# with the simulation stepping beside it in real time (its compute as `auto` chooses: on the
# GPU where it has a path), with how far the simulation kept up and how often a fresh force
# reached the haptic channel (GPU_CHECK_PROFILE=0 leaves them out). The procedures with a GPU
# path run once more (`:shared`) with their models on the frames' own device (one wgpu device
# and queue for both) rather than one of their own: what sharing costs the frames and the
# fresh forces, beside the two-device figures.
[ "${GPU_CHECK_PROFILE:-1}" = 1 ] && for run in sandbox nephrectomy rectum cholecystectomy catheter myotomy \
    rectum:shared cholecystectomy:shared; do
    p=${run%%:*}
    if [ "$run" = "$p" ]; then
        name=$p list=profile-gpu share=()
    else
        name=$p-shared list=profile-shared share=(--share-device)
    fi
    echo "== vesalius profile $p ${share[*]}" >&2
    if timeout 150 "$bin" profile "$p" "${share[@]}" --json >"$out/$name-profile.json" 2>"$out/$name-profile.err"; then
        python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print(json.dumps({'profile': sys.argv[2], 'device': d.get('device'), 'gpu_devices': d.get('gpu_devices'), 'frame_ms': d.get('frame_ms'), 'cpu': d.get('vesalius', {}).get('cpu'), 'beside': d.get('beside')}))" \
            "$out/$name-profile.json" "$p" >>"$out/$list.jsonl" || true
    else
        status=1
        tail -5 "$out/$name-profile.err" >&2
    fi
done
# One summary: every line of every procedure, in one JSON array.
{
    printf '['
    first=1
    for f in "$out"/*-gpu.jsonl; do
        while IFS= read -r line; do
            [ -n "$line" ] || continue
            [ $first -eq 1 ] || printf ','
            printf '\n%s' "$line"
            first=0
        done <"$f"
    done
    printf '\n]\n'
} | tee "$out/summary.json"
# The issue's targets against what was measured (scripts/gpu-targets.py), last.
python3 "$(dirname "$0")/gpu-targets.py" "$out" | tee "$out/targets.json" || status=1
exit $status
