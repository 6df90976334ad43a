#!/usr/bin/env bash
# A real single-node Slurm on this machine for the deploy/slurm recipes: munged, slurmctld and
# slurmd on localhost with a configuration generated here, in a private directory (no system
# files touched, no systemd). Sourced by the Slurm test; after `slurm_start DIR`, sbatch, squeue,
# scancel and sinfo talk to it (SLURM_CONF), and `slurm_stop` ends every daemon it started.
# The daemons run as root (slurmd starts job steps as their users): as this user when it is root,
# else through passwordless sudo. Needs Debian's slurm-wlm and munge.

SLURM_AS_ROOT=()

slurm_free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

slurm_start() {
  local dir=$1
  SLURM_AS_ROOT=()
  if [ "$(id -u)" -ne 0 ]; then
    sudo -n true 2>/dev/null || { echo "single-node Slurm: needs root or passwordless sudo (slurmd starts job steps as their users)" >&2; return 1; }
    SLURM_AS_ROOT=(sudo -n -E)
  fi
  for tool in munged mungekey slurmctld slurmd sbatch squeue scancel sinfo; do
    command -v "$tool" >/dev/null || { echo "single-node Slurm: $tool not found (install slurm-wlm and munge)" >&2; return 1; }
  done
  SLURM_DIR=$dir
  mkdir -p "$dir/state" "$dir/spool" "$dir/munge"
  chmod 700 "$dir/munge"
  "${SLURM_AS_ROOT[@]}" mungekey --create --keyfile="$dir/munge/munge.key"
  "${SLURM_AS_ROOT[@]}" chmod 400 "$dir/munge/munge.key"
  "${SLURM_AS_ROOT[@]}" munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
    --pid-file="$dir/munge/munged.pid" --log-file="$dir/munge/munged.log" --seed-file="$dir/munge/munged.seed"
  local host ctld_port slurmd_port
  host=$(hostname -s)
  ctld_port=$(slurm_free_port)
  slurmd_port=$(slurm_free_port)
  # The node offers more CPUs than the machine has (config_overrides): the farm allocation and a
  # worker array must run side by side on two cores, as they would on separate nodes.
  cat >"$dir/slurm.conf" <<CONF
ClusterName=lightfarm-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SlurmdParameters=config_overrides
ReturnToService=2
KillWait=10
NodeName=$host NodeAddr=127.0.0.1 CPUs=8 RealMemory=4000 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
  export SLURM_CONF=$dir/slurm.conf
  # LIGHTFARM_SLURM_DAEMON marks the daemons and the step daemons slurmd forks (they inherit its
  # environment), so that slurm_stop finds every one of them.
  "${SLURM_AS_ROOT[@]}" env SLURM_CONF="$SLURM_CONF" LIGHTFARM_SLURM_DAEMON="$dir" slurmctld -i
  "${SLURM_AS_ROOT[@]}" env SLURM_CONF="$SLURM_CONF" LIGHTFARM_SLURM_DAEMON="$dir" slurmd
  local _
  for _ in $(seq 60); do
    if sinfo -h -o %T 2>/dev/null | grep -qx idle; then return 0; fi
    sleep 1
  done
  echo "single-node Slurm: the node did not become idle" >&2
  sinfo >&2 || true
  tail -20 "$dir/slurmctld.log" "$dir/slurmd.log" >&2 || true
  return 1
}

# Submits a batch job to this Slurm, marked so that slurm_stop can find its processes.
slurm_sbatch() { LIGHTFARM_SLURM_JOB=$SLURM_DIR sbatch "$@"; }

# Every process whose environment holds NAME=VALUE.
slurm_pids_with() {
  local environ pid
  for environ in /proc/[0-9]*/environ; do
    pid=${environ#/proc/}
    pid=${pid%/environ}
    "${SLURM_AS_ROOT[@]+"${SLURM_AS_ROOT[@]}"}" cat "$environ" 2>/dev/null | tr '\0' '\n' | grep -qxF "$1" && echo "$pid"
  done
  return 0
}

slurm_stop() {
  local dir=${SLURM_DIR:-} _ pids
  [ -n "$dir" ] || return 0
  # Jobs first, while slurmctld can still cancel them; then whatever they left, the daemons and
  # their step daemons (a killed slurmd leaves its slurmstepd processes running).
  scancel --user="$(id -un)" >/dev/null 2>&1 || true
  for _ in $(seq 20); do [ -z "$(squeue -h 2>/dev/null)" ] && break; sleep 0.5; done
  pids=$(slurm_pids_with "LIGHTFARM_SLURM_JOB=$dir")
  [ -z "$pids" ] || "${SLURM_AS_ROOT[@]+"${SLURM_AS_ROOT[@]}"}" kill -KILL $pids 2>/dev/null || true
  pids=$(slurm_pids_with "LIGHTFARM_SLURM_DAEMON=$dir")
  [ -z "$pids" ] || "${SLURM_AS_ROOT[@]+"${SLURM_AS_ROOT[@]}"}" kill -KILL $pids 2>/dev/null || true
  "${SLURM_AS_ROOT[@]+"${SLURM_AS_ROOT[@]}"}" munged --stop --socket="$dir/munge/munge.socket" >/dev/null 2>&1 || true
  SLURM_DIR=
}
