#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A real single-node Slurm cluster on this machine, for the campaign tests and for trying the
# slurm executor of `fnmpc campaign` (docs/campaigns.md). Debian bookworm's slurm-wlm 22.05 and
# munge (scripts/install-deps.sh); works as root in a container without systemd: every daemon
# is started by hand, with its files in one temporary folder, nothing under /etc or /run.
#
#   scripts/slurm-local.sh start [DIR]   start munged, slurmctld and slurmd with their files in
#                                        DIR (default: a new /tmp/fnmpc-slurm.XXXXXX), wait until
#                                        `sinfo` shows the node idle, print on stdout the
#                                        environment to use:  eval "$(scripts/slurm-local.sh start)"
#   scripts/slurm-local.sh stop [DIR]    stop the daemons of DIR (default: the folder of
#                                        $SLURM_CONF) and remove DIR
#   scripts/slurm-local.sh status [DIR]  sinfo and squeue of that cluster
#
# The cluster: one node (this host's short name, reached at 127.0.0.1) with the CPUs and memory
# `slurmd -C` reports, one partition `local` (default, no time limit), select/cons_tres with
# CR_CPU so that the tasks of a job array run at the same time up to the CPUs,
# proctrack/linuxproc and task/none (no cgroup: a container rarely has cgroup v2 delegation),
# no accounting database (sacct is unavailable; finished jobs stay visible to
# `scontrol show job` for MinJobAge=3600 s). munged runs on its own socket with a fresh key
# (AuthInfo=socket=...), slurmctld and slurmd on two free TCP ports, so the cluster does not
# clash with a system one. Diagnostics go to stderr; the daemons' logs are DIR/*.log.
set -euo pipefail

die() { echo "slurm-local: $*" >&2; exit 1; }
log() { echo "slurm-local: $*" >&2; }

cmd=${1:-}
[[ -n $cmd ]] || { sed -n '3,17p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
shift

dir_from_env() {
  [[ -n ${SLURM_CONF:-} ]] || die "no DIR given and SLURM_CONF is not set"
  dirname "$SLURM_CONF"
}

stop_pidfile() {  # stop_pidfile FILE NAME: SIGTERM, wait up to 10 s, then SIGKILL
  local f=$1 name=$2 pid
  [[ -s $f ]] || return 0
  pid=$(cat "$f")
  if kill -0 "$pid" 2>/dev/null; then
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    if kill -0 "$pid" 2>/dev/null; then
      log "$name ($pid) did not stop on SIGTERM, killing it"
      kill -KILL "$pid" 2>/dev/null || true
    fi
  fi
  rm -f "$f"
}

stop_cluster() {
  local d=$1
  [[ -f $d/.fnmpc-slurm-local ]] || die "$d is not a folder of scripts/slurm-local.sh"
  # Jobs first (their slurmstepd belong to slurmd), then the daemons in reverse order.
  if [[ -s $d/slurmctld.pid ]] && kill -0 "$(cat "$d/slurmctld.pid")" 2>/dev/null; then
    SLURM_CONF=$d/slurm.conf scancel --quiet --user="$(id -un)" 2>/dev/null || true
  fi
  stop_pidfile "$d/slurmd.pid" slurmd
  stop_pidfile "$d/slurmctld.pid" slurmctld
  stop_pidfile "$d/munged.pid" munged
  rm -rf "$d"
  log "stopped, removed $d"
}

free_port() {
  /usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

start_cluster() {
  local d=$1
  for b in munged mungekey slurmctld slurmd sinfo; do
    command -v "$b" >/dev/null || [[ -x /usr/sbin/$b ]] || die "$b not found: scripts/install-deps.sh installs slurm-wlm and munge"
  done
  export PATH=/usr/sbin:/usr/bin:$PATH
  mkdir -p "$d"
  chmod 700 "$d"
  touch "$d/.fnmpc-slurm-local"
  mkdir -p "$d/state" "$d/spool"
  # If anything below fails, tear down what was started.
  trap 'log "start failed; logs:"; tail -n 20 "$d"/*.log >&2 2>/dev/null || true; stop_cluster "$d"' ERR

  # munge: a fresh key, our own socket, pid, log and seed files.
  mungekey --create --keyfile="$d/munge.key" --force
  chmod 600 "$d/munge.key"
  munged --force --key-file="$d/munge.key" --socket="$d/munge.socket" \
    --pid-file="$d/munged.pid" --log-file="$d/munged.log" --seed-file="$d/munged.seed"
  for _ in $(seq 50); do [[ -S $d/munge.socket ]] && break; sleep 0.1; done
  [[ -S $d/munge.socket ]] || { log "munged did not create its socket"; false; }

  local host cpus node ctld_port d_port user
  host=$(hostname -s)
  user=$(id -un)
  # `slurmd -C`: NodeName=vm CPUs=2 Boards=1 SocketsPerBoard=1 CoresPerSocket=2 ThreadsPerCore=1 RealMemory=24105
  node=$(slurmd -C | head -n 1)
  [[ $node == NodeName=* ]] || { log "unexpected slurmd -C output: $node"; false; }
  cpus=$(sed -n 's/.*CPUs=\([0-9]*\).*/\1/p' <<<"$node")
  node=${node#NodeName=* }
  ctld_port=$(free_port)
  d_port=$(free_port)
  while [[ $d_port == "$ctld_port" ]]; do d_port=$(free_port); done

  cat >"$d/slurm.conf" <<EOF
# Written by scripts/slurm-local.sh: a single-node test cluster (docs/campaigns.md).
ClusterName=fnmpc-local
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$d/munge.socket
StateSaveLocation=$d/state
SlurmdSpoolDir=$d/spool/%n
SlurmctldPidFile=$d/slurmctld.pid
SlurmdPidFile=$d/slurmd.pid
SlurmctldLogFile=$d/slurmctld.log
SlurmdLogFile=$d/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
LaunchParameters=use_interactive_step
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
ReturnToService=2
MinJobAge=3600
MailProg=/bin/true
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
KillWait=5
NodeName=$host NodeAddr=127.0.0.1 $node State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
  export SLURM_CONF=$d/slurm.conf
  # -i: ignore the (empty) saved state of an earlier cluster in DIR.
  slurmctld -f "$SLURM_CONF" -i
  slurmd -f "$SLURM_CONF"
  local state=""
  for _ in $(seq 300); do
    state=$(sinfo -h -n "$host" -o '%t' 2>/dev/null || true)
    [[ $state == idle ]] && break
    sleep 0.1
  done
  [[ $state == idle ]] || { log "node $host is '${state:-unreachable}', not idle after 30 s"; false; }
  trap - ERR
  log "cluster up in $d: node $host, $cpus CPUs, partition local (sinfo: $state)"
  echo "export SLURM_CONF=$d/slurm.conf"
}

case "$cmd" in
  start)
    if [[ $# -ge 1 ]]; then
      d=$1
      [[ ! -e $d || -z $(ls -A "$d" 2>/dev/null) ]] || die "$d exists and is not empty"
      d=$(mkdir -p "$d" && cd "$d" && pwd)
    else
      d=$(mktemp -d /tmp/fnmpc-slurm.XXXXXX)
    fi
    start_cluster "$d"
    ;;
  stop)
    d=${1:-$(dir_from_env)}
    [[ -d $d ]] || die "no folder $d"
    stop_cluster "$(cd "$d" && pwd)"
    ;;
  status)
    d=${1:-$(dir_from_env)}
    SLURM_CONF=$d/slurm.conf sinfo
    SLURM_CONF=$d/slurm.conf squeue
    ;;
  *) die "unknown command $cmd (start, stop, status)" ;;
esac
