#!/usr/bin/env bash
# Runs paraview_gui.py inside the ParaView GUI and passes only if the script itself wrote
# "pass" to $FLUIDCAST_OUT/result.txt (the GUI's own exit code says nothing about the script).
#   run_paraview_gui.sh PARAVIEW_EXECUTABLE
set -u
result="$FLUIDCAST_OUT/result.txt"
rm -f "$result"
"$1" --script="$(dirname "$0")/paraview_gui.py" --exit
cat "$result" 2> /dev/null || echo "paraview_gui.py did not run"
grep -q '^pass' "$result"
