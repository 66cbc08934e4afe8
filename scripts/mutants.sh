#!/usr/bin/env bash
# Mutation testing of the core crates with cargo-mutants (crates.io `cargo-mutants`, installed
# here on first use): every mutant of a crate's code is built and must make its tests fail.
#
#   bash scripts/mutants.sh                      # fluidcast-plan and fluidcast-render
#   bash scripts/mutants.sh fluidcast-sph        # other crates
#   FILTER='cell_bounds|ValueBound' bash scripts/mutants.sh fluidcast-plan   # some functions
#
# Mutants of fluidcast-plan run the tests of fluidcast-plan and fluidcast-render (the plan's
# guarantees are tested through the renderer); every other crate runs its own tests plus
# fluidcast-render's. Results: mutants.out/CRATE/ (caught.txt, missed.txt, timeout.txt,
# unviable.txt) and a score line per crate: caught / (caught + missed + timeout).
# Tests run under cargo-nextest, which stops at the first failing test: a caught mutant costs
# its build and one test, a missed one the whole suite (about 40 s on 2 cores; about 1,000
# mutants in plan + render). JOBS=N runs N at a time (each in its own copy of the tree);
# SHARD=k/n runs every n-th mutant from the k-th (round robin), to spread a crate over runs.
# ITERATE=1 retests only the mutants the last run of the same crate (and shard) left alive.
# cargo-mutants shards after it drops the caught ones, so ITERATE=1 with SHARD=k/n tests the
# k-th n-th of what is left, not of the first run's shard k; every other run's results stand.
# A mutant whose tests run past TIMEOUT seconds (default 150, four times the whole suite) is
# stopped and listed as timed out: the suite did not pass it, but it is counted apart.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
command -v cargo-mutants > /dev/null || cargo install --locked cargo-mutants@27.1.0
command -v cargo-nextest > /dev/null || cargo install --locked cargo-nextest
# The tests that read ../shared/data must find it from cargo-mutants' copy of the tree (which
# has no ../shared beside it), and must fail rather than skip without it.
if [ -d "$root/../shared/data" ]; then
  export FLUIDCAST_SHARED_DATA="$(cd "$root/../shared/data" && pwd)" FLUIDCAST_REQUIRE_DATA=1
fi
crates=("$@")
[ ${#crates[@]} -gt 0 ] || crates=(fluidcast-plan fluidcast-render)
for crate in "${crates[@]}"; do
  dir="rust/$crate"
  [ -d "$dir" ] || { echo "no crate $crate under rust/" >&2; exit 2; }
  out="mutants.out/$crate${SHARD:+-shard-${SHARD//\//-of-}}"
  mkdir -p "$out"
  args=(-f "$dir/src/*.rs" --test-package "$crate" --test-package fluidcast-render
        -j "${JOBS:-1}" -o "$out" --timeout "${TIMEOUT:-150}" --test-tool nextest)
  [ -z "${FILTER:-}" ] || args+=(-F "$FILTER")
  [ -z "${SHARD:-}" ] || args+=(--shard "$SHARD" --sharding round-robin)
  # ITERATE=1: test again only what the last run in this output folder did not catch.
  [ -z "${ITERATE:-}" ] || args+=(--iterate)
  # cargo mutants exits 2 when mutants survive, 3 when some time out: the score below is the
  # result. Anything else (4: the unmutated tests fail) is an error.
  rc=0
  cargo mutants "${args[@]}" || rc=$?
  case $rc in 0 | 2 | 3) ;; *) exit "$rc" ;; esac
  m="$out/mutants.out"
  caught=$(wc -l < "$m/caught.txt"); missed=$(wc -l < "$m/missed.txt")
  timeout=$(wc -l < "$m/timeout.txt"); unviable=$(wc -l < "$m/unviable.txt")
  viable=$((caught + missed + timeout))
  echo "$crate: $caught of $viable viable mutants caught" \
    "($(( viable ? 100 * caught / viable : 0 )) %); $missed missed (see $m/missed.txt)," \
    "$timeout timed out, $unviable unviable"
  if [ -f "$m/previously_caught.txt" ]; then
    echo "  (ITERATE: these counts are of the mutants left alive before;" \
      "$(wc -l < "$m/previously_caught.txt") were caught or unviable in earlier runs)"
  fi
done
