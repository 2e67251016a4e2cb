#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, for the batch tests:
#   tests/slurm/slurm-node.sh start DIR [OWNER_PID]
#                                         writes slurm.conf, cgroup.conf and a munge key into DIR,
#                                         starts munged, slurmctld and slurmd (as root) with their
#                                         state, logs and pid files in DIR, and waits for the node
#                                         to be idle; then `export SLURM_CONF=DIR/slurm.conf` reaches it.
#                                         With OWNER_PID, the daemons are stopped when that process
#                                         ends, however it ends (a test killed by a timeout included).
#   tests/slurm/slurm-node.sh stop DIR    stops the three daemons it started, by their pid files
# Exit 77 from start: Slurm cannot run here (not root, a package missing), the
# reason on the last line of stderr; the caller skips saying so. Any other
# non-zero exit is a failure to start, with the daemons' logs printed.
set -uo pipefail

cannot() { echo "slurm-node: cannot start Slurm here: $*" >&2; exit 77; }

# A TCP port in 20000-59999 nothing listens on, other than $1.
free_port() {
  local port
  for _ in $(seq 200); do
    port=$(( 20000 + RANDOM % 40000 ))
    [ "$port" = "${1:-}" ] && continue
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null || { echo "$port"; return 0; }
  done
  return 1
}

stop() {
  local dir=$1 pid
  # slurmd first, so it does not re-register with a controller that is going.
  for daemon in slurmd slurmctld munged; do
    [ -f "$dir/$daemon.pid" ] || continue
    pid=$(cat "$dir/$daemon.pid")
    [ -n "$pid" ] && kill "$pid" 2>/dev/null
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null
    rm -f "$dir/$daemon.pid"
  done
  return 0
}

start() {
  local dir=$1 owner=${2:-}
  [ "$(id -u)" = 0 ] || cannot "slurmd must run as root (running as uid $(id -u))"
  for tool in munged slurmctld slurmd sbatch squeue sinfo scontrol; do
    command -v "$tool" >/dev/null 2>&1 || [ -x "/usr/sbin/$tool" ] ||
      cannot "$tool is missing (Debian packages slurm-wlm munge; scripts/install-deps.sh installs them)"
  done
  export PATH="$PATH:/usr/sbin"
  # Ports chosen free rather than fixed, so a node of another checkout's tests on this machine
  # (or one a killed test left) does not collide with this one; a system Slurm's 6817/6818 lie below the range.
  local ctld_port slurmd_port
  ctld_port=$(free_port) || { echo "slurm-node: no free TCP port found in 20000-59999" >&2; exit 1; }
  slurmd_port=$(free_port "$ctld_port") || { echo "slurm-node: no free TCP port found in 20000-59999" >&2; exit 1; }
  mkdir -p "$dir"/{state,spool,log}
  chmod 700 "$dir"
  local host cpus memory_mb
  host=$(hostname -s)
  cpus=$(nproc)
  [ "$cpus" -gt 2 ] && cpus=2
  # Below what slurmd -C finds, or the node is drained for having less than it claims.
  memory_mb=$(( $(slurmd -C 2>/dev/null | sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p') / 2 ))
  [ "$memory_mb" -gt 0 ] || memory_mb=1000

  dd if=/dev/urandom of="$dir/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge.key"
  munged --force --key-file="$dir/munge.key" --socket="$dir/munge.socket" --pid-file="$dir/munged.pid" \
         --log-file="$dir/log/munged.log" --seed-file="$dir/munged.seed" ||
    { cat "$dir/log/munged.log" >&2; exit 1; }

  cat > "$dir/slurm.conf" <<CONF
ClusterName=photorig-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge.socket
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
ReturnToService=2
MailProg=/bin/true
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# Finished jobs stay visible to squeue/scontrol a while; photorig batch status reads its own records after that.
MinJobAge=300
SchedulerType=sched/builtin
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$memory_mb State=UNKNOWN
PartitionName=batch Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
  cat > "$dir/cgroup.conf" <<CONF
# No cgroups: processes are tracked through /proc (proctrack/linuxproc).
CgroupAutomount=no
ConstrainCores=no
ConstrainRAMSpace=no
CONF
  export SLURM_CONF="$dir/slurm.conf"
  # Started through setsid so the test's process group does not hold them; they write their own pid files.
  setsid slurmctld -i > "$dir/log/slurmctld.out" 2>&1 < /dev/null &
  setsid slurmd > "$dir/log/slurmd.out" 2>&1 < /dev/null &
  local state=""
  for _ in $(seq 150); do
    state=$(sinfo -h -N -n "$host" -o %t 2>/dev/null)
    case "$state" in
      idle)
        echo "slurm-node: $host idle (ports $ctld_port, $slurmd_port), SLURM_CONF=$dir/slurm.conf" >&2
        [ -n "$owner" ] && setsid bash -c 'while kill -0 "$1" 2>/dev/null; do sleep 1; done; "$2" stop "$3"' \
          reaper "$owner" "$(readlink -f "$0")" "$dir" > /dev/null 2>&1 < /dev/null &
        return 0 ;;
    esac
    for daemon in slurmctld slurmd; do
      if [ -f "$dir/$daemon.pid" ] && ! kill -0 "$(cat "$dir/$daemon.pid")" 2>/dev/null; then
        echo "slurm-node: $daemon exited; logs:" >&2
        tail -n 30 "$dir"/log/*.log "$dir"/log/*.out >&2
        stop "$dir"
        exit 1
      fi
    done
    sleep 0.2
  done
  echo "slurm-node: node $host not idle after 30 s (state '$state'); logs:" >&2
  tail -n 30 "$dir"/log/*.log "$dir"/log/*.out >&2
  stop "$dir"
  exit 1
}

case "${1:-}" in
  start) [ -n "${2:-}" ] || { echo "usage: $0 start DIR [OWNER_PID] | stop DIR" >&2; exit 2; }; start "$2" "${3:-}" ;;
  stop) [ -n "${2:-}" ] || { echo "usage: $0 start DIR [OWNER_PID] | stop DIR" >&2; exit 2; }; stop "$2" ;;
  *) echo "usage: $0 start DIR [OWNER_PID] | stop DIR" >&2; exit 2 ;;
esac
