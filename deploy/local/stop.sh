#!/usr/bin/env bash
# Stops what deploy/local/start.sh started (by the pids it recorded): SIGTERM drains workers
# (they finish their task) and the coordinator; state stays in the run dir for the next start.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
run_dir=${1:-$root/out/farm}
for f in "$run_dir"/worker-*.pid "$run_dir"/coordinator.pid; do
  [ -f "$f" ] || continue
  pid=$(cat "$f")
  kill -TERM "$pid" 2>/dev/null || true
  for _ in $(seq 300); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  rm -f "$f"
done
