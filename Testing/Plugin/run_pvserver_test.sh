#!/usr/bin/env bash
# pvserver + pvpython client in a private network namespace (loopback only: pvserver listens on
# every interface and has no bind option), connected over 127.0.0.1; the volume is rendered on
# the server (remote rendering) and the screenshot compared with the pvpython baseline.
#   run_pvserver_test.sh [--mpirun MPIRUN --np N] PVSERVER PVPYTHON SCRIPT [script args...]
# With --mpirun, the server is `MPIRUN -np N pvserver` (sub-domain rendering over N ranks).
# Exit 77 (skipped) when network namespaces are not available (not root, no user namespaces).
set -uo pipefail
if [ "${1:-}" != "--inside" ]; then
  if ! unshare -n true 2>/dev/null; then
    echo "unshare -n not permitted here: skipping"
    exit 77
  fi
  exec unshare -n bash "$0" --inside "$@"
fi
shift
LAUNCH=()
if [ "${1:-}" = "--mpirun" ]; then
  LAUNCH=("$2" -np "$4")
  shift 4
fi
PVSERVER=$1 PVPYTHON=$2 SCRIPT=$3
shift 3
ip link set lo up
PORT=11811
LOG=$(mktemp)
"${LAUNCH[@]}" "$PVSERVER" --server-port=$PORT --force-offscreen-rendering >"$LOG" 2>&1 &
SRV=$!
cleanup() { kill "$SRV" 2>/dev/null; wait "$SRV" 2>/dev/null; rm -f "$LOG"; }
trap cleanup EXIT
for _ in $(seq 300); do
  grep -q "Accepting connection" "$LOG" && break
  kill -0 "$SRV" 2>/dev/null || { echo "pvserver died:"; cat "$LOG"; exit 1; }
  sleep 0.2
done
grep -q "Accepting connection" "$LOG" || { echo "pvserver did not start:"; cat "$LOG"; exit 1; }
"$PVPYTHON" "$SCRIPT" --connect 127.0.0.1:$PORT "$@"
rc=$?
echo "---- pvserver log"
cat "$LOG"
exit $rc
