#!/usr/bin/env bash
# A single-node Slurm on this machine (for trying `pyorch sweep --cluster slurm`
# and for tests/test_slurm.py): munge + slurmctld + slurmd of Debian's slurm-wlm,
# one node with this machine's CPUs and memory (as `slurmd -C` reads them), one
# partition "debug", no accounting, no cgroups (works inside containers).
#
#   bash scripts/slurm_local.sh          # install (apt-get, as root) and start; idempotent
#   bash scripts/slurm_local.sh status   # exit 0 if the controller answers and the node is up
#   bash scripts/slurm_local.sh stop     # cancel every job, stop the daemons it started
#
# Needs root and apt-get (Debian/Ubuntu). Writes /etc/slurm/slurm.conf only if it is
# absent or was written by this script (it refuses to touch a real cluster's config).
# Daemons and state: /run/pyorch-slurm (pid files), /var/spool/pyorch-slurm, logs in
# /var/log/pyorch-slurm. The daemons are addressed at 127.0.0.1 (they bind to every
# interface, as Slurm does).
set -euo pipefail

CONF=/etc/slurm/slurm.conf
MARK="# written by pyorch scripts/slurm_local.sh"
RUN=/run/pyorch-slurm
SPOOL=/var/spool/pyorch-slurm
LOG=/var/log/pyorch-slurm
PARTITION=debug
say() { printf '[slurm_local] %s\n' "$*" >&2; }
die() { printf '[slurm_local] error: %s\n' "$*" >&2; exit 1; }

alive() { [ -f "$RUN/$1.pid" ] && kill -0 "$(cat "$RUN/$1.pid")" 2>/dev/null; }

node_name() { hostname -s; }

up() {  # controller answers and our node is usable (idle/mixed/allocated)
  command -v sinfo >/dev/null 2>&1 || return 1
  local st
  st=$(timeout 5 sinfo -h -N -n "$(node_name)" -o '%t' 2>/dev/null | head -1) || return 1
  case "$st" in idle*|mix*|alloc*|comp*) return 0 ;; *) return 1 ;; esac
}

install() {
  if command -v slurmctld >/dev/null 2>&1 && command -v slurmd >/dev/null 2>&1 \
     && command -v sbatch >/dev/null 2>&1 && command -v munged >/dev/null 2>&1; then
    return 0
  fi
  command -v apt-get >/dev/null 2>&1 || die "Slurm is not installed and apt-get is missing (Debian/Ubuntu only)"
  say "installing munge + Slurm (slurm-wlm: slurmctld slurmd slurm-client) with apt-get"
  apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    munge slurmctld slurmd slurm-client >/dev/null
}

write_conf() {
  if [ -f "$CONF" ] && ! head -1 "$CONF" | grep -qF "$MARK"; then
    die "$CONF exists and was not written by this script: refusing to replace a real cluster's configuration"
  fi
  local node cpus line
  node=$(node_name)
  # this machine as slurmd sees it: CPUs, sockets, cores, threads, RealMemory [MB]
  line=$(slurmd -C | head -1 | sed "s/^NodeName=[^ ]*/NodeName=$node/")
  echo "$line" | grep -q 'CPUs=[0-9]' || die "slurmd -C did not report the node: $line"
  cpus=$(echo "$line" | sed -n 's/.*CPUs=\([0-9]*\).*/\1/p')
  mkdir -p /etc/slurm
  cat > "$CONF.tmp" <<EOF
$MARK (single node; $(date -u +%FT%TZ))
ClusterName=pyorch-local
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
StateSaveLocation=$SPOOL/ctld
SlurmdSpoolDir=$SPOOL/d
SlurmctldPidFile=$RUN/slurmctld.pid
SlurmdPidFile=$RUN/slurmd.pid
SlurmctldLogFile=$LOG/slurmctld.log
SlurmdLogFile=$LOG/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
# a cancelled job gets SIGTERM, then SIGKILL after KillWait s (the engine checkpoints on SIGTERM)
KillWait=10
MinJobAge=60
SlurmctldTimeout=30
SlurmdTimeout=60
InactiveLimit=0
NodeName=${line#NodeName=} NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=$PARTITION Nodes=$node Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
EOF
  # an identical configuration (but the date) is kept, so running daemons need no restart
  if [ -f "$CONF" ] && diff -q <(tail -n +2 "$CONF") <(tail -n +2 "$CONF.tmp") >/dev/null; then
    rm -f "$CONF.tmp"
  else
    mv "$CONF.tmp" "$CONF"
    say "wrote $CONF: node $node, $cpus CPUs"
  fi
}

start_munge() {
  if timeout 5 munge -n </dev/null 2>/dev/null | timeout 5 unmunge >/dev/null 2>&1; then
    return 0  # a munged (ours or the system's) already answers
  fi
  [ -s /etc/munge/munge.key ] || { say "creating /etc/munge/munge.key"; mungekey --create --force; }
  mkdir -p /run/munge /var/log/munge /var/lib/munge
  chown munge:munge /run/munge /var/log/munge /var/lib/munge /etc/munge/munge.key 2>/dev/null || true
  chmod 0400 /etc/munge/munge.key
  if id munge >/dev/null 2>&1; then
    runuser -u munge -- /usr/sbin/munged --pid-file=/run/munge/munged.pid
  else
    /usr/sbin/munged --force --pid-file=/run/munge/munged.pid
  fi
  cp /run/munge/munged.pid "$RUN/munged.pid"
  for _ in $(seq 50); do
    if munge -n </dev/null 2>/dev/null | unmunge >/dev/null 2>&1; then return 0; fi
    sleep 0.1
  done
  die "munged did not start (see /var/log/munge/munged.log)"
}

start() {
  if up && [ -f "$CONF" ] && head -1 "$CONF" | grep -qF "$MARK"; then
    say "up: $(sinfo -h -o '%P %D nodes, %c CPUs/node, %m MB/node, %t' | head -1)"
    return 0
  fi
  [ "$(id -u)" = "0" ] || die "the local Slurm is not running; start it as root (it installs with apt-get and starts daemons)"
  install
  mkdir -p "$RUN" "$SPOOL/ctld" "$SPOOL/d" "$LOG"
  write_conf
  start_munge
  if ! alive slurmctld; then
    say "starting slurmctld"
    slurmctld -i   # -i: ignore state of an earlier controller that cannot be read back
  fi
  if ! alive slurmd; then
    say "starting slurmd"
    slurmd
  fi
  for _ in $(seq 150); do  # 30 s
    if up; then
      say "up: $(sinfo -h -o '%P %D nodes, %c CPUs/node, %m MB/node, %t' | head -1)"
      return 0
    fi
    # a node left down/drained by an earlier run: the configuration is ours, resume it
    st=$(timeout 5 sinfo -h -N -n "$(node_name)" -o '%t' 2>/dev/null | head -1 || true)
    case "$st" in down*|drain*) scontrol update nodename="$(node_name)" state=resume >/dev/null 2>&1 || true ;; esac
    sleep 0.2
  done
  die "Slurm did not come up in 30 s (node state: $(sinfo -h -N -o '%t %E' 2>&1 | head -1)); logs in $LOG"
}

stop() {
  if up || alive slurmctld; then
    scancel --full --quiet --user="$(id -un)" 2>/dev/null || true
    scancel --full --quiet 2>/dev/null || true
  fi
  for d in slurmd slurmctld munged; do
    if alive "$d"; then
      pid=$(cat "$RUN/$d.pid")
      kill "$pid" 2>/dev/null || true
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      say "stopped $d ($pid)"
    fi
    rm -f "$RUN/$d.pid"
  done
}

case "${1:-start}" in
  start) start ;;
  stop) stop ;;
  status) up && { sinfo; exit 0; } || { echo "Slurm is not up" >&2; exit 1; } ;;
  *) die "usage: $0 [start|stop|status]" ;;
esac
