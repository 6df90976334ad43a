#!/usr/bin/env bash
# Checks the sbatch scripts on a single-node Slurm (Debian's slurm-wlm with slurmctld and slurmd
# on localhost): starts the farm allocation, submits the example scene, waits, cancels.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
command -v sbatch >/dev/null || { echo "sbatch not found: install slurm-wlm" >&2; exit 2; }
mkdir -p "$HOME/.lightfarm"
[ -f "$HOME/.lightfarm/token" ] || openssl rand -hex 32 >"$HOME/.lightfarm/token"
export LIGHTFARM_BIN=$root/build LIGHTFARM_PORT=${LIGHTFARM_PORT:-7270}
job=$(sbatch --parsable --nodes 1 --ntasks 1 --cpus-per-task 2 "$root/deploy/slurm/lightfarm-farm.sbatch")
trap 'scancel "$job"' EXIT
for _ in $(seq 60); do [ "$(squeue -h -j "$job" -o %T)" = RUNNING ] && break; sleep 1; done
sleep 3
"$root/build/lightfarm" submit "$root/scenes/cornell-box/scene.pbrt" --server "localhost:$LIGHTFARM_PORT" \
  --token-file "$HOME/.lightfarm/token" --resolution 32x32 --lights 1000 --wait --quiet --out /tmp/slurm-check.exr
echo "slurm check passed"
