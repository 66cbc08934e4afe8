#!/usr/bin/env bash
# Runs a command with its own Xvfb display (Debian's VTK/ParaView need X even offscreen).
# - A random display number: `xvfb-run -a`, or letting Xvfb pick (-displayfd alone), hands
#   out the lowest free number, so a test can get the number another test's Xvfb is just
#   releasing, and that server's shutdown then unlinks the new server's socket ("bad X
#   server connection").
# - Ready means Xvfb has written the number to -displayfd, which it does once it accepts
#   connections (the socket file appears earlier).
# - -noreset: by default an X server resets when its last client disconnects and refuses
#   connections meanwhile; VTK and ParaView close a first connection and open another, and
#   under load that second one landed in the reset ("bad X server connection" with the
#   server alive and its socket present).
#   with_xvfb.sh COMMAND [ARGS...]
set -u
for attempt in 1 2 3 4 5; do
  n=$(( (RANDOM % 900) + 100 ))
  [[ -e "/tmp/.X${n}-lock" || -e "/tmp/.X11-unix/X${n}" ]] && continue
  fdfile=$(mktemp)
  Xvfb ":${n}" -displayfd 3 -noreset -screen 0 1024x768x24 -nolisten tcp 3> "$fdfile" > /dev/null 2>&1 &
  xpid=$!
  for _ in $(seq 1 200); do
    [[ -s "$fdfile" ]] && break
    kill -0 "$xpid" 2> /dev/null || break
    sleep 0.05
  done
  ready=$([[ -s "$fdfile" ]] && echo 1)
  rm -f "$fdfile"
  if [[ -n "$ready" ]] && kill -0 "$xpid" 2> /dev/null; then
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
