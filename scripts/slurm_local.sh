#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for testing `rtsim sweep --slurm` against a real
# Slurm (Debian's slurm-wlm and munge): a fresh munge key, munged, and slurmctld and slurmd on
# loopback with non-default ports, every file under DIR (nothing in /etc or /var).
#
#   scripts/slurm_local.sh start DIR    # prints the SLURM_CONF to export (alone on stdout)
#   scripts/slurm_local.sh stop DIR     # stops what start started
# Whatever the daemons print (munged warns when the host's name does not resolve) goes to
# stderr, so stdout holds the path and nothing else. A daemon that does not start is named with
# the log to read, and what did start is stopped.
set -euo pipefail
cmd="${1:-}"
dir="${2:-}"
[ -n "$cmd" ] && [ -n "$dir" ] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }
dir="$(mkdir -p "$dir" && cd "$dir" && pwd)"
conf="$dir/slurm.conf"

stop() {
    if [ -f "$conf" ]; then
        SLURM_CONF="$conf" scontrol shutdown >/dev/null 2>&1 || true
    fi
    for pid in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
        [ -f "$pid" ] && kill "$(cat "$pid")" 2>/dev/null || true
    done
    sleep 1
    for pid in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
        [ -f "$pid" ] && kill -9 "$(cat "$pid")" 2>/dev/null || true
        rm -f "$pid"
    done
}

case "$cmd" in
stop)
    stop
    exit 0
    ;;
start) ;;
*)
    echo "$0: unknown command $cmd (start or stop)" >&2
    exit 2
    ;;
esac

for b in munged slurmctld slurmd sbatch; do
    command -v "$b" >/dev/null 2>&1 || [ -x "/usr/sbin/$b" ] ||
        { echo "$0: $b is not installed (Debian: slurm-wlm munge)" >&2; exit 1; }
done
stop
mkdir -p "$dir/state" "$dir/spool" "$dir/munge"
chmod 700 "$dir/munge"
rm -f "$dir/munge/munge.key"
dd if=/dev/urandom bs=1 count=1024 of="$dir/munge/munge.key" 2>/dev/null
chmod 400 "$dir/munge/munge.key"
# Under `set -e` a daemon that fails to start would end the script before it says which.
fail() {
    echo "$0: $1 did not start; see $2" >&2
    [ ! -f "$2" ] || tail -n 5 "$2" >&2
    stop
    exit 1
}
/usr/sbin/munged --force --socket="$dir/munge/munge.sock" --key-file="$dir/munge/munge.key" \
    --log-file="$dir/munge/munged.log" --pid-file="$dir/munge/munged.pid" \
    --seed-file="$dir/munge/munged.seed" >&2 || fail munged "$dir/munge/munged.log"
host="$(hostname -s)"
user="$(id -un)"
port="${RTSIM_SLURM_PORT:-16817}"
cat >"$conf" <<CONF
ClusterName=rtsimtest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.sock
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmUser=$user
SlurmdUser=root
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=1000 State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
/usr/sbin/slurmctld -f "$conf" >&2 || fail slurmctld "$dir/slurmctld.log"
/usr/sbin/slurmd -f "$conf" >&2 || fail slurmd "$dir/slurmd.log"
# Ready once the node is idle.
for _ in $(seq 1 60); do
    if SLURM_CONF="$conf" sinfo -h -o %T 2>/dev/null | grep -q idle; then
        echo "$conf"
        exit 0
    fi
    sleep 0.5
done
echo "$0: the node did not come up; see $dir/slurmctld.log and $dir/slurmd.log" >&2
stop
exit 1
