#!/usr/bin/env bash
# A private single-node Slurm cluster on this machine, for trying sharded bakes and for the
# test that runs them (cli/tests/slurm.rs). Needs Debian's slurm-wlm and munge, and root (slurmd
# starts jobs as their users).
#
#   scripts/slurm/cluster.sh start DIR [PORT]   # munged, slurmctld and slurmd; config in DIR
#   export SLURM_CONF=DIR/slurm.conf            # then sbatch, squeue, scontrol use it
#   scripts/slurm/cluster.sh stop DIR
#
# Everything lives in DIR (a short path: munge's socket path is limited to 108 bytes): its own
# munge key and socket, state, spool, logs; ports PORT and PORT+1 (default 16817). Nothing in
# /etc is read or changed.
set -euo pipefail

action=${1:?usage: cluster.sh start|stop DIR [PORT]}
dir=$(mkdir -p "${2:?usage: cluster.sh start|stop DIR [PORT]}" && cd "$2" && pwd)
port=${3:-16817}

stop() {
  for daemon in slurmd slurmctld munged; do
    if [ -f "$dir/$daemon.pid" ]; then
      kill "$(cat "$dir/$daemon.pid")" 2>/dev/null || true
      rm -f "$dir/$daemon.pid"
    fi
  done
}

start() {
  mkdir -p "$dir/state" "$dir/spool" "$dir/log"
  if [ ! -f "$dir/munge.key" ]; then
    head -c 1024 /dev/urandom > "$dir/munge.key"
    chmod 600 "$dir/munge.key"
  fi
  munged --force --socket="$dir/munge.sock" --key-file="$dir/munge.key" --pid-file="$dir/munged.pid" \
    --log-file="$dir/log/munged.log" --seed-file="$dir/munge.seed"
  cat > "$dir/slurm.conf" <<CONF
ClusterName=kage
SlurmctldHost=localhost
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
AuthInfo=socket=$dir/munge.sock
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/pgid
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
SchedulerParameters=kill_invalid_depend
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=kage Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
  export SLURM_CONF="$dir/slurm.conf"
  slurmctld -c -i
  slurmd -N localhost
  # Ready when the node is idle.
  for _ in $(seq 1 60); do
    if sinfo -h -o %T 2>/dev/null | grep -q idle; then
      echo "export SLURM_CONF=$dir/slurm.conf"
      return 0
    fi
    sleep 0.5
  done
  echo "cluster.sh: the node did not come up; logs in $dir/log" >&2
  stop
  return 1
}

case "$action" in
  start) start ;;
  stop) stop ;;
  *) echo "usage: cluster.sh start|stop DIR [PORT]" >&2; exit 2 ;;
esac
