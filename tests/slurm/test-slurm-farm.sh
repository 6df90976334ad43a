#!/usr/bin/env bash
# The deploy/slurm recipes on a real single-node Slurm (single-node-slurm.sh): the farm
# allocation (lightfarm-farm.sbatch) takes a progressive reference job; a worker array
# (lightfarm-workers.sbatch) joins while it runs; one array element is killed mid-task
# (SIGKILL to its worker, as a lost node would). The job must finish every pass, the killed
# task must have been retried, and the image must equal `lightfarm render` of the same passes
# bit for bit. Usage: test-slurm-farm.sh BUILD_DIR. Needs root or passwordless sudo, slurm-wlm
# and munge.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
work=$(mktemp -d /tmp/lightfarm-slurm.XXXXXX)
# shellcheck source=tests/slurm/single-node-slurm.sh
source "$root/tests/slurm/single-node-slurm.sh"
fail() {
  echo "FAIL: $*" >&2
  for log in "$work"/*.log; do [ -f "$log" ] && { echo "--- $log" >&2; tail -20 "$log" >&2; }; done
  exit 1
}
# The daemons' files are root's when they ran through sudo.
cleanup() { slurm_stop; "${SLURM_AS_ROOT[@]+"${SLURM_AS_ROOT[@]}"}" rm -rf "$work"; }
trap cleanup EXIT

slurm_start "$work/slurm" || fail "could not start a single-node Slurm"
token=$work/token
openssl rand -hex 32 >"$token"
port=$(slurm_free_port)
server=127.0.0.1:$port
export LIGHTFARM_BIN=$build LIGHTFARM_STATE=$work/farm-state LIGHTFARM_TOKEN_FILE=$token LIGHTFARM_PORT=$port
export LIGHTFARM_COORDINATOR_ARGS="--lease-timeout 3" LIGHTFARM_WORKER_ARGS="--log-level debug"
lf() { "$build/lightfarm" "$@"; }

farm=$(slurm_sbatch --parsable --nodes 1 --ntasks 1 --cpus-per-task 1 --output "$work/farm-%j.log" \
  "$root/deploy/slurm/lightfarm-farm.sbatch")
for _ in $(seq 60); do lf status --server "$server" --token-file "$token" >/dev/null 2>&1 && break; sleep 1; done
lf status --server "$server" --token-file "$token" >/dev/null || fail "the farm allocation's coordinator did not come up"

scene=$root/scenes/cornell-box/scene.pbrt
# About a second per task on one thread, so the kill lands mid-task.
opts=(--method brute --resolution 128x128 --lights 20000 --seed 5 --passes 3 --param rows_per_slice=1024)
job=$(lf submit "$scene" --server "$server" --token-file "$token" --quiet "${opts[@]}")
echo "slurm: farm allocation $farm, job $job"

# Workers join while the job runs.
array=$(slurm_sbatch --parsable --array=1-2 --cpus-per-task 1 --output "$work/worker-%A_%a.log" \
  --export=ALL,LIGHTFARM_COORDINATOR="$server" "$root/deploy/slurm/lightfarm-workers.sbatch")
victim_log=$work/worker-${array}_1.log
for _ in $(seq 600); do grep -q "leased" "$victim_log" 2>/dev/null && break; sleep 0.1; done
grep -q "leased" "$victim_log" 2>/dev/null || fail "array element 1 never leased a task"
# Mid-task, without a chance to hand the task back (a node lost or preempted): SIGKILL to the
# element's worker. A plain scancel sends SIGTERM first, on which a worker finishes its task.
pkill -KILL -f "lightfarm-cache-${array}-1" || fail "array element 1's worker is not running"
scancel "${array}_1"
echo "slurm: killed array element ${array}_1 after: $(grep leased "$victim_log" | tail -1)"

lf watch "$job" --server "$server" --token-file "$token" >"$work/watch.log" 2>&1 || fail "the job did not finish: $(tail -1 "$work/watch.log")"
lf fetch "$job" --server "$server" --token-file "$token" --out "$work/farm.exr" >/dev/null
lf render "$scene" "${opts[@]}" --quiet --out "$work/embedded.exr"

python3 - "$work/farm.json" <<'PY' || fail "stats"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["passes"] == 3, s["passes"]
assert s["farm"]["attempts"] > s["farm"]["tasks"], ("no task was retried", s["farm"])
print("slurm: passes %d, tasks %d, attempts %d" % (s["passes"], s["farm"]["tasks"], s["farm"]["attempts"]))
PY
idiff -fail 0 -failpercent 0 -warn 0 "$work/farm.exr" "$work/embedded.exr" >"$work/idiff.log" 2>&1 \
  || fail "the Slurm farm's image differs from the embedded render: $(cat "$work/idiff.log")"
echo "slurm: the farm's 3 passes equal the embedded render bit for bit"
