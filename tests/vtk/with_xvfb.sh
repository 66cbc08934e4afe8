#!/usr/bin/env bash
# Runs a command with its own Xvfb display (Debian's VTK/ParaView need X even offscreen).
# Unlike `xvfb-run -a`, which can hand two quickly started tests the same display number,
# this picks a random free display and retries if the server does not come up.
#   with_xvfb.sh COMMAND [ARGS...]
set -u
for attempt in 1 2 3 4 5; do
  n=$(( (RANDOM % 900) + 100 ))
  [[ -e "/tmp/.X${n}-lock" || -e "/tmp/.X11-unix/X${n}" ]] && continue
  Xvfb ":${n}" -screen 0 1024x768x24 -nolisten tcp > /dev/null 2>&1 &
  xpid=$!
  for _ in $(seq 1 100); do
    [[ -e "/tmp/.X11-unix/X${n}" ]] && break
    kill -0 "$xpid" 2> /dev/null || break
    sleep 0.05
  done
  if [[ -e "/tmp/.X11-unix/X${n}" ]] && kill -0 "$xpid" 2> /dev/null; then
    DISPLAY=":${n}" "$@"
    status=$?
    kill "$xpid" 2> /dev/null
    wait "$xpid" 2> /dev/null
    exit "$status"
  fi
  kill "$xpid" 2> /dev/null
  wait "$xpid" 2> /dev/null
done
echo "with_xvfb.sh: could not start Xvfb" >&2
exit 1
