# Sourced by Tools/run-tests.sh and Tools/run-example.sh: one Xvfb for everything that renders.
#   start_xvfb   starts it on the first free display (unless DISPLAY is set) and exports DISPLAY
#   stop_xvfb    stops the one start_xvfb started
# -noreset matters: by default Xvfb resets when its last client disconnects, and a client that
# connects during the reset fails with "bad X server connection" (seen in CI between two
# consecutive ParaView tests).
INR_XVFB_PID=""
start_xvfb() {
  if [ -n "${DISPLAY:-}" ] || ! command -v Xvfb >/dev/null; then return 0; fi
  local n
  for n in $(seq 90 110); do
    if [ -e /tmp/.X11-unix/X$n ] || [ -e /tmp/.X$n-lock ]; then continue; fi
    Xvfb :$n -screen 0 1920x1200x24 -nolisten tcp -noreset >/dev/null 2>&1 &
    INR_XVFB_PID=$!
    for _ in $(seq 50); do [ -e /tmp/.X11-unix/X$n ] && break; sleep 0.1; done
    export DISPLAY=:$n
    return 0
  done
  echo "start_xvfb: no free X display in :90-:110" >&2
}
stop_xvfb() {
  if [ -n "$INR_XVFB_PID" ]; then kill "$INR_XVFB_PID" 2>/dev/null || true; INR_XVFB_PID=""; unset DISPLAY; fi
}
