#!/usr/bin/env bash
# Starts a coordinator and N workers on this machine (used by CI and for trying the farm).
#   deploy/local/start.sh [--workers N] [--port P] [--run-dir DIR] [--token-file F] [--lease-timeout S]
# Prints the coordinator address; the dashboard is at http://127.0.0.1:P+2/ (log line "dashboard");
# pids and logs are in the run dir; stop with deploy/local/stop.sh.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${LIGHTFARM_BIN:-$root/build}
workers=2 port=7070 run_dir=$root/out/farm token_file="" lease=30 threads=1
while [ $# -gt 0 ]; do
  case "$1" in
    --workers) workers=$2; shift 2 ;;
    --port) port=$2; shift 2 ;;
    --run-dir) run_dir=$2; shift 2 ;;
    --token-file) token_file=$2; shift 2 ;;
    --lease-timeout) lease=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    *) echo "start.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$run_dir/state" "$run_dir/logs"
auth=()
[ -n "$token_file" ] && auth=(--token-file "$token_file")

"$bin/lightfarm-coordinator" --listen "127.0.0.1:$port" --state-dir "$run_dir/state" \
  --metrics-listen "127.0.0.1:$((port + 1))" --http-listen "127.0.0.1:$((port + 2))" \
  --lease-timeout "$lease" "${auth[@]}" \
  >"$run_dir/logs/coordinator.out" 2>"$run_dir/logs/coordinator.log" &
echo $! >"$run_dir/coordinator.pid"
# Wait until it listens (it prints the port).
for _ in $(seq 100); do
  grep -q "listening on port" "$run_dir/logs/coordinator.out" 2>/dev/null && break
  kill -0 "$(cat "$run_dir/coordinator.pid")" 2>/dev/null || { cat "$run_dir/logs/coordinator.log" >&2; exit 1; }
  sleep 0.1
done
for i in $(seq "$workers"); do
  "$bin/lightfarm-worker" --coordinator "127.0.0.1:$port" --threads "$threads" --name "local-$i" \
    --cache-dir "$run_dir/cache-$i" "${auth[@]}" >"$run_dir/logs/worker-$i.out" 2>"$run_dir/logs/worker-$i.log" &
  echo $! >"$run_dir/worker-$i.pid"
done
echo "dashboard: http://127.0.0.1:$((port + 2))/" >&2
echo "127.0.0.1:$port"
