#!/usr/bin/env bash
# Runs a ParaView command, retrying (up to 3 attempts) only when it failed because an X client
# could not connect to the shared Xvfb ("bad X server connection"). The main cause, Xvfb resetting
# when its last client leaves, is removed by -noreset (Tools/xvfb.sh); this guards the two MPI
# ranks opening the display at the same instant. Any other failure is returned at once, unchanged.
set -u
log=$(mktemp)
trap 'rm -f "$log"' EXIT
for attempt in 1 2 3; do
  "$@" 2>&1 | tee "$log"
  rc=${PIPESTATUS[0]}
  if [ "$rc" -eq 0 ] || ! grep -q "bad X server connection" "$log"; then
    exit "$rc"
  fi
  echo "retry_x_race: attempt $attempt hit the X connection race; retrying" >&2
  sleep 2
done
exit "$rc"
