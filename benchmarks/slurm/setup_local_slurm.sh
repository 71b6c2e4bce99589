#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, from Debian's packages, to exercise
# profiles/slurm (docs/cluster.md). Needs root; not part of the tests.
#
#     SUDO=$([ "$(id -u)" = 0 ] || echo sudo)        # empty for root, `sudo` for a user
#     $SUDO bash benchmarks/slurm/setup_local_slurm.sh          # install, configure, start
#     $SUDO bash benchmarks/slurm/setup_local_slurm.sh stop     # stop what it started
#
# It installs slurmctld, slurmd, slurmdbd, munge and mariadb-server with apt-get, writes
# /etc/slurm/slurm.conf (one node, this host, all its CPUs, its memory less a margin; one
# partition `debug`, the default) and /etc/slurm/slurmdbd.conf, and starts munged, mariadb,
# slurmdbd, slurmctld and slurmd directly (no systemd needed: containers and VMs without an
# init system work). Job accounting goes through slurmdbd into MariaDB because
# snakemake-executor-plugin-slurm asks `sacct` for the state of its jobs and `sacctmgr` whether
# the account it submits with exists, as on a production cluster; the script registers the
# cluster, an account (`railtherm`, or $SLURM_ACCOUNT_NAME) and root (and $SUDO_USER) as its
# users. Processes are tracked without cgroups (proctrack/linuxproc, task/none).
#
# Each service it starts (one that was not running) is written to the state file
# /var/lib/railtherm-slurm/started; `stop` stops those and no other (a MariaDB or munged that
# was running before is left running), then empties the file.
#
# Run it again to rewrite the configuration and start whatever is not running (a daemon that
# is running is restarted if its configuration changed). Logs: /var/log/slurm/.
set -euo pipefail

ACCOUNT=${SLURM_ACCOUNT_NAME:-railtherm}
PARTITION=debug
CLUSTER=railtherm
CONF_DIR=/etc/slurm
LOG_DIR=/var/log/slurm
STATE=/var/lib/railtherm-slurm/started  # the services this script started, one a line

[ "$(id -u)" = 0 ] || { echo "setup_local_slurm: run as root" >&2; exit 1; }

running() { [ -f "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }
pidfile() { echo "/run/$1.pid"; }  # of a Slurm daemon
started() {  # started NAME: record that this script started NAME (once)
    mkdir -p "$(dirname "$STATE")"
    grep -qx "$1" "$STATE" 2>/dev/null || echo "$1" >>"$STATE"
}

if [ "${1:-}" = stop ]; then
    [ -s "$STATE" ] || { echo "setup_local_slurm: nothing started by this script"; exit 0; }
    # the reverse order of starting: Slurm's daemons before the database and munged
    for name in slurmd slurmctld slurmdbd mariadb munge; do
        grep -qx "$name" "$STATE" || continue
        case "$name" in
            mariadb | munge)
                echo "stopping $name"
                [ -x "/etc/init.d/$name" ] && "/etc/init.d/$name" stop || true
                ;;
            *)
                if running "$(pidfile "$name")"; then
                    echo "stopping $name (pid $(cat "$(pidfile "$name")"))"
                    kill "$(cat "$(pidfile "$name")")"
                fi
                ;;
        esac
    done
    rm -f "$STATE"
    exit 0
fi

# --- packages ---------------------------------------------------------------------------------
packages=(slurmctld slurmd slurmdbd slurm-client munge mariadb-server)
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi
echo "slurm $(dpkg-query -W -f='${Version}' slurmctld), munge $(dpkg-query -W -f='${Version}' munge)," \
    "mariadb $(dpkg-query -W -f='${Version}' mariadb-server)"

# --- configuration ----------------------------------------------------------------------------
host=$(hostname -s)
cpus=$(nproc)
mem_total=$(awk '/^MemTotal:/ {print int($2 / 1024)}' /proc/meminfo)
margin=$(( mem_total / 10 > 512 ? mem_total / 10 : 512 ))
real_memory=$(( mem_total - margin ))  # MB left to jobs: the rest for the OS and the daemons

mkdir -p "$CONF_DIR" "$LOG_DIR" /var/spool/slurmctld /var/spool/slurmd
chown slurm:slurm "$LOG_DIR" /var/spool/slurmctld

cat >"$CONF_DIR/slurm.conf.new" <<EOF
# Single-node test cluster written by benchmarks/slurm/setup_local_slurm.sh (railtherm).
ClusterName=$CLUSTER
SlurmctldHost=$host(127.0.0.1)
SlurmUser=slurm
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
MpiDefault=none
# no cgroups: works in containers and VMs without a delegated cgroup tree
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
ReturnToService=2
# finished jobs stay visible to squeue/scontrol for 5 minutes (sacct keeps them for good)
MinJobAge=300
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=$LOG_DIR/slurmctld.log
SlurmdLogFile=$LOG_DIR/slurmd.log
# accounting through slurmdbd (MariaDB): sacct and sacctmgr answer, accounts are enforced
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
AccountingStorageEnforce=associations
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=30
JobCompType=jobcomp/none
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$real_memory State=UNKNOWN
PartitionName=$PARTITION Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF

# the database password: kept from an earlier run, else a new random one
password=""
if [ -f "$CONF_DIR/slurmdbd.conf" ]; then
    password=$(sed -n 's/^StoragePass=//p' "$CONF_DIR/slurmdbd.conf")
fi
[ -n "$password" ] || password=$(head -c 18 /dev/urandom | base64 | tr -dc 'A-Za-z0-9')
umask 077
cat >"$CONF_DIR/slurmdbd.conf.new" <<EOF
# slurmdbd of the single-node test cluster (benchmarks/slurm/setup_local_slurm.sh)
AuthType=auth/munge
DbdHost=localhost
SlurmUser=slurm
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=slurm
StoragePass=$password
StorageLoc=slurm_acct_db
LogFile=$LOG_DIR/slurmdbd.log
PidFile=/run/slurmdbd.pid
EOF
umask 022
changed=0
for f in slurm.conf slurmdbd.conf; do
    if ! cmp -s "$CONF_DIR/$f.new" "$CONF_DIR/$f"; then
        mv "$CONF_DIR/$f.new" "$CONF_DIR/$f"
        changed=1
    else
        rm "$CONF_DIR/$f.new"
    fi
done
chmod 644 "$CONF_DIR/slurm.conf"
chown slurm:slurm "$CONF_DIR/slurmdbd.conf"
chmod 600 "$CONF_DIR/slurmdbd.conf"

# --- daemons ----------------------------------------------------------------------------------
wait_for() {  # wait_for SECONDS DESCRIPTION COMMAND...: until COMMAND succeeds
    local seconds=$1 what=$2
    shift 2
    for _ in $(seq "$seconds"); do
        "$@" >/dev/null 2>&1 && return 0
        sleep 1
    done
    echo "setup_local_slurm: $what did not come up in $seconds s (see $LOG_DIR)" >&2
    exit 1
}

for name in munge mariadb; do
    if ! "/etc/init.d/$name" status >/dev/null 2>&1; then
        "/etc/init.d/$name" start
        started "$name"
    fi
done
wait_for 10 munged bash -c 'munge -n | unmunge'
wait_for 30 mariadb mysqladmin ping
mysql <<EOF
CREATE DATABASE IF NOT EXISTS slurm_acct_db;
CREATE USER IF NOT EXISTS 'slurm'@'localhost';
ALTER USER 'slurm'@'localhost' IDENTIFIED BY '$password';
GRANT ALL ON slurm_acct_db.* TO 'slurm'@'localhost';
EOF

restart_or_start() {  # restart_or_start NAME: start, or restart on a changed config
    local name=$1 pid
    pid=$(pidfile "$name")
    if running "$pid" && [ "$changed" = 1 ]; then
        kill "$(cat "$pid")"
        for _ in $(seq 20); do running "$pid" || break; sleep 0.5; done
        "/usr/sbin/$name"  # restarted: started by this script only if it was before
    elif ! running "$pid"; then
        "/usr/sbin/$name"  # each daemon forks into the background
        started "$name"
    fi
}

restart_or_start slurmdbd
wait_for 30 slurmdbd sacctmgr -n list cluster
sacctmgr -i -Q add cluster "$CLUSTER" >/dev/null 2>&1 || true

restart_or_start slurmctld
wait_for 30 slurmctld scontrol ping
restart_or_start slurmd

# the account and its users (sacctmgr -i: no confirmation; an existing one is left as is)
sacctmgr -i -Q add account "$ACCOUNT" Cluster="$CLUSTER" \
    Description="railtherm test account" Organization=railtherm >/dev/null 2>&1 || true
for user in root ${SUDO_USER:-}; do
    sacctmgr -i -Q add user "$user" Account="$ACCOUNT" DefaultAccount="$ACCOUNT" \
        Cluster="$CLUSTER" >/dev/null 2>&1 || true
done

# the node: idle, or resumed if the controller holds it down from an earlier run
node_idle() { [ "$(sinfo -h -n "$host" -o %T)" = idle ]; }
for _ in $(seq 30); do
    node_idle && break
    case "$(sinfo -h -n "$host" -o %T)" in
        down* | drain*) scontrol update NodeName="$host" State=RESUME 2>/dev/null || true ;;
    esac
    sleep 1
done
wait_for 5 "node $host (idle)" node_idle

sinfo
sacctmgr -n -P list associations user=root format=cluster,account,user
echo "setup_local_slurm: ready; partition '$PARTITION', account '$ACCOUNT'"
