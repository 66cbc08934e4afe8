#!/bin/bash
# The GPU measurements issue 49 asks for, as one run on a lent GPU machine (which has no
# network and no Rust): per-stage GPU timestamps of the GPU backend on each scene, iso-surfaces
# and RBF with shadows on the GPU backend, and the CPU for scale.
#
# Here, first:  bash scripts/device_gpu_bench.sh prepare SCENE.vtu...
#   copies target/release/fluidcast (build it first) and the scenes into .devrun/, and the
#   Vulkan loader's .debs into .gl/ (both git-ignored through .git/info/exclude).
# Then through the device tool: run `bash scripts/device_gpu_bench.sh` with carry
#   [".devrun", ".gl"] (64 MiB in all: pick scenes to fit). Its output is also in $OUT/log.
# Scenes are rendered by velocity; SIZE (default 1024x1024) and T (seconds per command) apply.
set -u
cd "$(dirname "$0")/.."
if [ "${1:-}" = prepare ]; then
  shift
  mkdir -p .devrun .gl /tmp/amd64/partial
  for d in /.devrun/ /.gl/; do grep -qx "$d" .git/info/exclude || echo "$d" >> .git/info/exclude; done
  cp target/release/fluidcast .devrun/ && cp "$@" .devrun/
  o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
  apt-get $o update >/dev/null && (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 \
    libopengl0 libgl1 libglx0 libgles2)
  du -sh .devrun .gl
  exit
fi
R=${OUT:-/tmp/device_out}; mkdir -p "$R"
exec > >(tee "$R/log") 2>&1
for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
ls /usr/share/vulkan/icd.d/*nvidia* >/dev/null 2>&1 ||
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv
FC=.devrun/fluidcast S=${SIZE:-1024x1024} T=${T:-120}
for f in .devrun/*.vtu .devrun/*.vtp; do
  [ -e "$f" ] || continue
  echo "=== $f: GPU backend, off and 0.004, per-stage GPU timestamps"
  timeout "$T" $FC bench "$f" --array velocity --backend gpu --size "$S" --views 4 \
    --tolerances off,0.004 --no-reference --json "$R/$(basename "$f").json" 2>&1 | tail -12
  echo "=== $f: the same without subgroup operations (scans and sort in workgroup memory)"
  FLUIDCAST_GPU_SUBGROUPS=0 timeout "$T" $FC bench "$f" --array velocity --backend gpu \
    --size "$S" --views 2 --tolerances off --no-reference 2>&1 | tail -4
  echo "=== $f: iso 0.5 and RBF with shadows (4 spp) on the GPU backend"
  timeout "$T" $FC render "$f" --array velocity --backend gpu --iso 0.5 --size "$S" \
    -o "$R/iso.png" --stats "$R/$(basename "$f").iso.json" 2>&1 | tail -2
  timeout "$T" $FC render "$f" --array velocity --backend gpu --field rbf --shadows --spp 4 \
    --size "$S" -o "$R/rbf.png" --stats "$R/$(basename "$f").rbf.json" 2>&1 | tail -2
  [ -e "$R/$(basename "$f").rbf.json" ] && python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['timings'])" "$R/$(basename "$f").rbf.json"
  echo "=== $f: CPU backend on this machine's cores, for scale"
  timeout "$T" $FC bench "$f" --array velocity --backend cpu --size "$S" --views 2 \
    --tolerances off,0.004 --no-reference 2>&1 | tail -4
done
echo "=== done"
