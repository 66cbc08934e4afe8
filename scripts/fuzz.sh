#!/usr/bin/env bash
# Long fuzzing run of fluidcast's readers and renderer (the test command runs a 20,000-input
# smoke run of the same harness): mutated VTK XML (every encoding), legacy .vtk, .pvd, PNG
# and EXR inputs, one in 20 that parses also rendered, under a 4 GiB address-space limit.
#
#   bash scripts/fuzz.sh [INPUTS] [SEED]      # default 1000000 inputs, seed 1
#
# Prints progress every 5 s and a summary; findings are saved under target/fuzz-out/
# (panic-N.EXT; current.bin holds the input that was running if the process died; hang.bin
# an input that ran longer than 10 s). Exit code 0 when nothing was found.
# Extra seed folders: FLUIDCAST_FUZZ_SEEDS="dir1 dir2" (e.g. ../shared/data/*/ for real files).
#
#   bash scripts/fuzz.sh --files [CASES] [SEED]        # default 100000 cases, seed 1
#   bash scripts/fuzz.sh --properties [CASES] [SEED]   # default 100000 cases each, seed 1
#
# --files: inputs of several files (fluidcast-fuzz-files): random graphs of .pvtu summaries
# and .pvd collections naming each other (cycles, a file listing itself, the same piece
# 2000 times), seed pieces (some mutated), FIFOs, links (loops, dangling), folders, missing,
# '..' and absolute paths, opened as the CLI opens its input, read and rendered small, under
# a 4 GiB address-space limit (the test command runs 3000). Exit code 0 when nothing was
# found.
#
# --properties: random values (inf, NaN, negative, out-of-range enumerations, unknown names)
# for the ParaView representation's properties and the VTK mapper's setters, each followed by
# a render of good data, defaults restored and the image compared every 10 cases
# (tests/vtk/pvbatch_property_fuzz.py in pvbatch, on the plugin the test command builds in
# build/; the test command runs 200 of each). Exit code 0 when the view never broke.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
if [ "${1:-}" = --files ]; then
  cases="${2:-100000}"
  seed="${3:-1}"
  cargo build --release -q -p fluidcast-fuzz
  out="$root/target/fuzz-files"
  mkdir -p "$out"
  (ulimit -v 4194304; exec target/release/fluidcast-fuzz-files --cases "$cases" --seed "$seed" \
    --out "$out" tests/fixtures) && rc=0 || rc=$?
  case $rc in
    0) echo "fuzz --files: no findings" ;;
    1) echo "fuzz --files: findings kept under $out (panic-N folders)" ;;
    3) echo "fuzz --files: a hang, kept as $out/case" ;;
    *) echo "fuzz --files: the process died (exit $rc); the case is $out/case" ;;
  esac
  exit $rc
fi
if [ "${1:-}" = --properties ]; then
  cases="${2:-100000}"
  seed="${3:-1}"
  plugin="$root/build/lib/paraview-plugins/fluidcast/fluidcast.so"
  [ -f "$plugin" ] || { echo "fuzz: no plugin at $plugin: run scripts/setup_vtk.sh" >&2; exit 2; }
  export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/fluidcast-runtime-$(id -u)}"
  mkdir -p -m 700 "$XDG_RUNTIME_DIR"
  out="$root/target/fuzz-properties"
  mkdir -p "$out"
  exec env PYTHONPATH="$root/build/python" tests/vtk/with_xvfb.sh \
    env LD_PRELOAD="$root/build/lib/libfluidcast_expat_fix.so" pvbatch \
    tests/vtk/pvbatch_property_fuzz.py "$plugin" tests/fixtures/lattice_binary_none_h32.vtu \
    velocity "$out" "$cases" "$seed" 16x12
fi
inputs="${1:-1000000}"
seed="${2:-1}"
cargo build --release -q -p fluidcast-fuzz
out="$root/target/fuzz-out"
rm -rf "$out"
mkdir -p "$out"
# shellcheck disable=SC2086
(ulimit -v 4194304; exec target/release/fluidcast-fuzz --inputs "$inputs" --seed "$seed" \
  --render-every 20 --out "$out" tests/fixtures ${FLUIDCAST_FUZZ_SEEDS:-}) && rc=0 || rc=$?
case $rc in
  0) echo "fuzz: no findings" ;;
  1) echo "fuzz: findings saved under $out" ;;
  3) echo "fuzz: a hang, saved as $out/hang.bin" ;;
  *) echo "fuzz: the process died (exit $rc); the input is $out/current.bin" ;;
esac
exit $rc
