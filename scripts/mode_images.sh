#!/usr/bin/env bash
# Renders the shared frames in every mode and option of the plan with the fluidcast CLI into
# OUT (default target/mode_images), or compares two such folders bit for bit:
#   scripts/mode_images.sh [OUT]            render (uses target/release/fluidcast)
#   scripts/mode_images.sh --compare A B    fluidcast compare --tolerance 0 on every image
# A refactor that must not change images renders before and after and compares.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${FLUIDCAST:-target/release/fluidcast}
if [[ "${1:-}" == "--compare" ]]; then
  a=$2 b=$3 bad=0 n=0
  for f in "$a"/*.exr; do
    n=$((n + 1))
    if ! "$BIN" compare "$f" "$b/$(basename "$f")" --tolerance 0 >/dev/null 2>&1; then
      echo "differs: $(basename "$f")"; bad=$((bad + 1))
    fi
  done
  echo "$n images compared, $bad differ"
  [[ $bad == 0 ]]
  exit
fi
OUT=${1:-target/mode_images}
mkdir -p "$OUT"
DATA=${SHARED_DATA:-../shared/data}
PY=$DATA/pysph_dambreak3d/dam_break_3d_fluid_00600.vtu
SPLASH=$DATA/splash_doubledambreak/DoubleDamBreak_r0.0125_0005.vtu
PYR=(--radius-array h --radius-scale 2)
SZ=(--size 160x120)
run() { # name, input, options...
  local name=$1 input=$2; shift 2
  "$BIN" render "$input" -o "$OUT/$name.exr" "${SZ[@]}" "$@" 2>"$OUT/$name.log" \
    || { echo "FAILED: $name"; cat "$OUT/$name.log"; exit 1; }
}
for s in py splash; do
  if [[ $s == py ]]; then IN=$PY; R=("${PYR[@]}"); else IN=$SPLASH; R=(); fi
  A=("${R[@]}" --array velocity)
  run "$s-adaptive" "$IN" "${A[@]}"
  run "$s-full-rate" "$IN" "${A[@]}" --error-tolerance off
  run "$s-no-probe" "$IN" "${A[@]}" --no-probe
  run "$s-reference" "$IN" "${A[@]}" --mode reference
  run "$s-perspective-grid" "$IN" "${A[@]}" --mode perspective-grid
  run "$s-density" "$IN" "${R[@]}" --field density
  run "$s-sph" "$IN" "${A[@]}" --field sph --kernel wendland-c2
  run "$s-tiles" "$IN" "${A[@]}" --tiles 4
  run "$s-pgrid-tiles" "$IN" "${A[@]}" --mode perspective-grid --tiles 3
  run "$s-lod" "$IN" "${A[@]}" --lod 4
  run "$s-iso" "$IN" "${A[@]}" --iso 0.5
  run "$s-iso-adaptive" "$IN" "${A[@]}" --iso 0.5 --mode adaptive
  run "$s-rbf-post" "$IN" "${A[@]}" --field rbf --spp 2
  run "$s-rbf-pre" "$IN" "${A[@]}" --field rbf --classification pre
  run "$s-rbf-density" "$IN" "${R[@]}" --field rbf --spp 2
  run "$s-shadows-sph" "$IN" "${A[@]}" --shadows --spp 2
  run "$s-shadows-rbf" "$IN" "${A[@]}" --field rbf --shadows
  if [[ -n "${WITH_GPU:-}" ]]; then
    run "$s-gpu" "$IN" "${A[@]}" --backend gpu
    run "$s-gpu-iso" "$IN" "${A[@]}" --iso 0.5 --backend gpu
  fi
done
if [[ -n "${WITH_GPU:-}" ]]; then
  # Software drivers end a shader invocation after 65,535 loop iterations: a small scene.
  LAT=tests/fixtures/lattice_appended-raw_none_h64.vtu
  run lattice-gpu-rbf "$LAT" --field rbf --array velocity --backend gpu
  run lattice-gpu-rbf-density "$LAT" --field rbf --backend gpu --spp 2
fi
echo "$(ls "$OUT"/*.exr | wc -l) images in $OUT"
