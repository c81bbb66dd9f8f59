#!/usr/bin/env bash
# One-node SLURM cluster for granchain's tests and CI, started by hand (no systemd).
#
#   scripts/slurm_cluster.sh up     [STATE_DIR]   install/configure/start, wait until the node is idle
#   scripts/slurm_cluster.sh down   [STATE_DIR]   stop our daemons, restore /etc/slurm/slurm.conf
#   scripts/slurm_cluster.sh status [STATE_DIR]   print sinfo and squeue
#
# STATE_DIR defaults to $GRANCHAIN_SLURM_STATE_DIR or /tmp/granchain-slurm. It holds the
# controller state, slurmd spool, logs and pid files. Every action is idempotent.
#
# Exit codes:
#   0  success (up: node idle; down: nothing of ours left running; status: cluster responding)
#   1  failure (up: daemons did not come up -> log tails printed; down: a daemon would not stop;
#      status: cluster not running / not responding)
#   2  usage error
#   3  this machine cannot host the cluster (not root, no apt-get, apt failed, ...): a single
#      line "slurm_cluster: cannot host: REASON" goes to stderr, so a test can skip with it
#   4  refused: a SLURM that is not ours is already running (we do not touch it)
#
# Facts this relies on (see shared slurm notes): the config must be at the default path
# /etc/slurm/slurm.conf (SLURM_CONF elsewhere breaks the jobstep's nested srun); no slurmdbd,
# so clients must use squeue rather than sacct; munged must run as the munge user.
#
# Environment knobs: GRANCHAIN_SLURM_WAIT_S (default 30) bounds the wait for an idle node.
set -euo pipefail

PROG=slurm_cluster
PARTITION=granchain
CLUSTER_NAME=granchain
CONF_DIR=/etc/slurm
CONF=$CONF_DIR/slurm.conf
BACKUP=$CONF_DIR/slurm.conf.granchain-backup
MARKER="# granchain-slurm-managed"
PACKAGES=(slurmctld slurmd slurm-client munge)
WAIT_S=${GRANCHAIN_SLURM_WAIT_S:-30}

log() { echo "$PROG: $*" >&2; }
die() { local code=$1; shift; log "$*"; exit "$code"; }
cannot_host() { echo "$PROG: cannot host: $*" >&2; exit 3; }

usage() {
    echo "usage: $0 up|down|status [STATE_DIR]" >&2
    exit 2
}

ACTION=${1:-}
[[ $# -le 2 ]] || usage
STATE_DIR=${2:-${GRANCHAIN_SLURM_STATE_DIR:-/tmp/granchain-slurm}}
case $STATE_DIR in /*) ;; *) STATE_DIR=$PWD/$STATE_DIR ;; esac
STATE_DIR=${STATE_DIR%/}

RUN_DIR=$STATE_DIR/run
LOG_DIR=$STATE_DIR/log
CTLD_PID=$RUN_DIR/slurmctld.pid
SLURMD_PID=$RUN_DIR/slurmd.pid
MUNGED_OURS=$STATE_DIR/munged.ours     # exists (holding munged's pid) iff we started munged
CTLD_LOG=$LOG_DIR/slurmctld.log
SLURMD_LOG=$LOG_DIR/slurmd.log

# ---------------------------------------------------------------- helpers

# pid_alive PIDFILE NAME -> prints the pid and succeeds if PIDFILE names a live process NAME
pid_alive() {
    local file=$1 name=$2 pid
    [[ -r $file ]] || return 1
    pid=$(tr -dc '0-9' <"$file")
    [[ -n $pid ]] || return 1
    [[ -r /proc/$pid/comm ]] || return 1
    [[ $(cat "/proc/$pid/comm" 2>/dev/null) == "$name" ]] || return 1
    echo "$pid"
}

# stop_pid PID NAME: SIGTERM, wait up to 15 s, then SIGKILL; fails if it survives
stop_pid() {
    local pid=$1 name=$2 i
    kill -TERM "$pid" 2>/dev/null || return 0
    for ((i = 0; i < 150; i++)); do
        [[ -d /proc/$pid && $(cat "/proc/$pid/comm" 2>/dev/null) == "$name" ]] || return 0
        sleep 0.1
    done
    log "$name (pid $pid) ignored SIGTERM for 15 s; sending SIGKILL"
    kill -KILL "$pid" 2>/dev/null || true
    for ((i = 0; i < 50; i++)); do
        [[ -d /proc/$pid ]] || return 0
        sleep 0.1
    done
    return 1
}

conf_is_ours() { [[ -f $CONF ]] && head -n 1 "$CONF" | grep -q "^$MARKER"; }

conf_state_dir() { # state dir recorded in our conf's marker line
    head -n 1 "$CONF" 2>/dev/null | sed -n "s|^$MARKER STATE_DIR=||p"
}

# foreign_daemons: prints "name:pid" for each running slurmctld/slurmd that is not ours
foreign_daemons() {
    local name pid ours
    for name in slurmctld slurmd; do
        if [[ $name == slurmctld ]]; then ours=$(pid_alive "$CTLD_PID" slurmctld || true)
        else ours=$(pid_alive "$SLURMD_PID" slurmd || true); fi
        for pid in $(pgrep -x "$name" || true); do
            [[ $pid == "$ours" ]] && continue
            # Skip zombies: the daemons' double-fork leaves short-lived ones when
            # pid 1 is slow to reap them (seen in containers).
            [[ $(awk '{print $3}' "/proc/$pid/stat" 2>/dev/null) == Z ]] && continue
            [[ -d /proc/$pid ]] && echo "$name:$pid"
        done
    done
}

print_log_tails() {
    local f
    for f in "$CTLD_LOG" "$SLURMD_LOG" "$LOG_DIR/slurmctld.stderr" "$LOG_DIR/slurmd.stderr" "$LOG_DIR/munged.stderr"; do
        [[ -s $f ]] || continue
        echo "----- tail of $f -----" >&2
        tail -n 40 "$f" >&2
    done
}

node_name() { hostname -s; }

node_state() { # e.g. "idle", "down*", "" when the controller does not answer
    timeout 5 sinfo -h -N -n "$(node_name)" -o '%T' 2>/dev/null | head -n 1 || true
}

# ---------------------------------------------------------------- up steps

check_can_host() {
    [[ $(id -u) -eq 0 ]] || cannot_host "must run as root (installs packages, writes $CONF)"
    command -v hostname >/dev/null && command -v pgrep >/dev/null && command -v nproc >/dev/null \
        || cannot_host "hostname/pgrep/nproc missing"
    command -v free >/dev/null || cannot_host "free (procps) missing"
    [[ -n $(node_name) ]] || cannot_host "hostname -s is empty"
}

missing_packages() {
    local p
    for p in "${PACKAGES[@]}"; do
        dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null | grep -qx installed || echo "$p"
    done
}

install_packages() {
    local missing
    mapfile -t missing < <(missing_packages)
    ((${#missing[@]} == 0)) && return 0
    command -v apt-get >/dev/null || cannot_host "packages ${missing[*]} missing and no apt-get"
    export DEBIAN_FRONTEND=noninteractive
    local aptopts=(-q -y --no-install-recommends -o DPkg::Lock::Timeout=120
        -o Dpkg::Options::=--force-confdef -o Dpkg::Options::=--force-confold)
    # Update the lists only when some package has no install candidate (fresh machine).
    local p need_update=0
    for p in "${missing[@]}"; do
        [[ $(apt-cache policy "$p" 2>/dev/null) == *"Candidate: "[0-9]* ]] || need_update=1
    done
    if ((need_update)); then
        log "apt-get update (no candidate for some of: ${missing[*]})"
        apt-get -q -o DPkg::Lock::Timeout=120 update >"$LOG_DIR/apt.log" 2>&1 \
            || cannot_host "apt-get update failed (see $LOG_DIR/apt.log)"
    fi
    # Keep package scripts from starting daemons (there is no systemd; we start them ourselves).
    local policy=/usr/sbin/policy-rc.d made_policy=0
    if [[ ! -e $policy ]]; then
        printf '#!/bin/sh\n# temporary, by granchain slurm_cluster.sh\nexit 101\n' >"$policy"
        chmod 755 "$policy"
        made_policy=1
    fi
    log "apt-get install ${missing[*]}"
    local rc=0
    apt-get "${aptopts[@]}" install "${missing[@]}" >>"$LOG_DIR/apt.log" 2>&1 || rc=$?
    if ((rc != 0 && need_update == 0)); then
        log "apt-get install failed; retrying after apt-get update"
        rc=0
        { apt-get -q -o DPkg::Lock::Timeout=120 update \
            && apt-get "${aptopts[@]}" install "${missing[@]}"; } >>"$LOG_DIR/apt.log" 2>&1 || rc=$?
    fi
    ((made_policy)) && rm -f "$policy"
    if ((rc != 0)); then
        tail -n 15 "$LOG_DIR/apt.log" >&2 || true
        cannot_host "apt-get install ${missing[*]} failed (exit $rc; see $LOG_DIR/apt.log)"
    fi
    mapfile -t missing < <(missing_packages)
    ((${#missing[@]} == 0)) || cannot_host "still missing after install: ${missing[*]}"
}

start_munge() {
    getent passwd munge >/dev/null || cannot_host "no munge user after installing munge"
    if [[ ! -s /etc/munge/munge.key ]]; then
        log "creating /etc/munge/munge.key"
        mungekey --create --keyfile=/etc/munge/munge.key >/dev/null 2>&1 \
            || dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
        chown munge:munge /etc/munge/munge.key
        chmod 0400 /etc/munge/munge.key
    fi
    install -d -o munge -g munge -m 0755 /run/munge
    if [[ -f $MUNGED_OURS ]] && pid_alive "$MUNGED_OURS" munged >/dev/null; then
        log "munged already running (started by us earlier)"
    elif pgrep -x munged >/dev/null; then
        log "munged already running (not started by us; left alone on down)"
    else
        log "starting munged as user munge"
        runuser -u munge -- /usr/sbin/munged >"$LOG_DIR/munged.stderr" 2>&1 \
            || { print_log_tails; die 1 "munged failed to start"; }
        local i pid=""
        for ((i = 0; i < 50; i++)); do
            pid=$(pid_alive /run/munge/munged.pid munged || true)
            [[ -n $pid ]] && break
            sleep 0.1
        done
        [[ -n $pid ]] || pid=$(pgrep -x -u munge munged | head -n 1 || true)
        [[ -n $pid ]] || { print_log_tails; die 1 "munged did not stay up"; }
        echo "$pid" >"$MUNGED_OURS"
    fi
    munge -n </dev/null | unmunge >/dev/null 2>&1 || die 1 "munge round trip (munge -n | unmunge) failed"
}

write_conf() { # writes the desired config to stdout
    local node cpus mem_total real_mem
    node=$(node_name)
    cpus=$(nproc)
    mem_total=$(free -m | awk '/^Mem:/ {print $2}')
    # "A bit under free -m": leave 5 % (at least 256 MB) so slurmd never sees less than declared.
    real_mem=$((mem_total - (mem_total / 20 > 256 ? mem_total / 20 : 256)))
    ((real_mem > 0)) || real_mem=$mem_total
    cat <<EOF
$MARKER STATE_DIR=$STATE_DIR
# Written by granchain scripts/slurm_cluster.sh; 'slurm_cluster.sh down' removes it and
# restores any earlier config from $BACKUP.
ClusterName=$CLUSTER_NAME
SlurmctldHost=$node(127.0.0.1)
SlurmUser=slurm
AuthType=auth/munge
CredType=cred/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
# Without a default a job with no --mem takes all of the node's memory.
DefMemPerCPU=1000
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$LOG_DIR/jobcomp.txt
ReturnToService=2
SchedulerType=sched/backfill
# Finished jobs stay visible to squeue for this long (the Snakemake profile polls squeue).
MinJobAge=300
KillWait=5
StateSaveLocation=$STATE_DIR/state
SlurmdSpoolDir=$STATE_DIR/spool
SlurmctldPidFile=$CTLD_PID
SlurmdPidFile=$SLURMD_PID
SlurmctldLogFile=$CTLD_LOG
SlurmdLogFile=$SLURMD_LOG
SlurmctldDebug=info
SlurmdDebug=info
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$real_mem State=UNKNOWN
PartitionName=$PARTITION Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
}

install_conf() { # returns 0 if the config changed
    local tmp
    tmp=$(mktemp)
    write_conf >"$tmp"
    install -d -m 0755 "$CONF_DIR"
    if [[ -f $CONF ]] && ! conf_is_ours; then
        if [[ -e $BACKUP ]]; then
            log "warning: $BACKUP already exists; keeping it and overwriting the foreign $CONF"
        else
            log "backing up existing $CONF to $BACKUP"
            cp -p "$CONF" "$BACKUP"
        fi
    fi
    if [[ -f $CONF ]] && cmp -s "$tmp" "$CONF"; then
        rm -f "$tmp"
        return 1
    fi
    log "writing $CONF (node $(node_name), $(nproc) CPUs, partition $PARTITION)"
    install -m 0644 "$tmp" "$CONF"
    rm -f "$tmp"
    return 0
}

prepare_state_dirs() {
    getent passwd slurm >/dev/null || cannot_host "no slurm user after installing the packages"
    install -d -m 0755 "$STATE_DIR"
    install -d -o slurm -g slurm -m 0755 "$STATE_DIR/state" "$RUN_DIR" "$LOG_DIR"
    install -d -m 0755 "$STATE_DIR/spool"
}

wait_idle() {
    local i state="" deadline=$((SECONDS + WAIT_S))
    while ((SECONDS < deadline)); do
        state=$(node_state)
        case $state in
            idle | mixed | allocated) return 0 ;;
        esac
        pid_alive "$CTLD_PID" slurmctld >/dev/null || { log "slurmctld exited"; return 1; }
        pid_alive "$SLURMD_PID" slurmd >/dev/null || { log "slurmd exited"; return 1; }
        sleep 0.5
    done
    log "node state after ${WAIT_S}s: '${state:-no answer from slurmctld}'"
    return 1
}

start_daemon() { # start_daemon NAME PIDFILE ARGS...
    local name=$1 pidfile=$2 i
    shift 2
    log "starting $name"
    rm -f "$pidfile"
    "/usr/sbin/$name" "$@" >"$LOG_DIR/$name.stderr" 2>&1 || { log "$name exited with $?"; return 1; }
    for ((i = 0; i < 100; i++)); do
        pid_alive "$pidfile" "$name" >/dev/null && return 0
        sleep 0.1
    done
    log "$name wrote no pid file $pidfile"
    return 1
}

fail_up() {
    log "up failed: $*"
    print_log_tails
    log "stopping what was started (logs stay in $LOG_DIR)"
    do_down >/dev/null 2>&1 || true
    exit 1
}

do_up() {
    local t0=$SECONDS
    check_can_host
    # Refuse before touching anything if a SLURM that is not ours is running.
    local foreign
    foreign=$(foreign_daemons | tr '\n' ' ')
    if [[ -n $foreign ]]; then
        if conf_is_ours && [[ $(conf_state_dir) != "$STATE_DIR" ]]; then
            die 4 "a granchain cluster with STATE_DIR=$(conf_state_dir) is running ($foreign); run '$0 down $(conf_state_dir)' first"
        fi
        die 4 "refusing: a SLURM not started by granchain is running (${foreign% }); stop it or run the slurm tests elsewhere"
    fi
    mkdir -p "$LOG_DIR"
    install_packages
    prepare_state_dirs
    start_munge
    local changed=0
    install_conf && changed=1
    local ctld slurmd
    ctld=$(pid_alive "$CTLD_PID" slurmctld || true)
    slurmd=$(pid_alive "$SLURMD_PID" slurmd || true)
    if [[ -n $ctld && -n $slurmd ]] && ((changed == 0)); then
        if wait_idle; then
            log "already up (slurmctld $ctld, slurmd $slurmd); partition $PARTITION"
            exit 0
        fi
        log "running daemons are not healthy; restarting them"
    fi
    [[ -n $slurmd ]] && stop_pid "$slurmd" slurmd
    [[ -n $ctld ]] && stop_pid "$ctld" slurmctld
    # -c: start from a clean job state, so runs do not inherit jobs from an earlier session.
    start_daemon slurmctld "$CTLD_PID" -c || fail_up "slurmctld did not start"
    start_daemon slurmd "$SLURMD_PID" || fail_up "slurmd did not start"
    wait_idle || fail_up "node $(node_name) did not become idle within ${WAIT_S}s"
    log "up in $((SECONDS - t0))s: node $(node_name) idle in partition $PARTITION (state in $STATE_DIR)"
}

# ---------------------------------------------------------------- down / status

do_down() {
    local rc=0 pid i
    [[ $(id -u) -eq 0 ]] || die 3 "cannot host: must run as root"
    local ctld slurmd
    ctld=$(pid_alive "$CTLD_PID" slurmctld || true)
    slurmd=$(pid_alive "$SLURMD_PID" slurmd || true)
    if [[ -n $ctld ]] && command -v scancel >/dev/null; then
        # Cancel leftover jobs so their slurmstepd/processes go away with the cluster.
        timeout 5 scancel -p "$PARTITION" >/dev/null 2>&1 || true
        for ((i = 0; i < 50; i++)); do
            [[ -z $(timeout 5 squeue -h -t RUNNING,COMPLETING -o %i 2>/dev/null) ]] && break
            sleep 0.2
        done
    fi
    if [[ -n $slurmd ]]; then log "stopping slurmd ($slurmd)"; stop_pid "$slurmd" slurmd || rc=1; fi
    if [[ -n $ctld ]]; then log "stopping slurmctld ($ctld)"; stop_pid "$ctld" slurmctld || rc=1; fi
    rm -f "$CTLD_PID" "$SLURMD_PID"
    if [[ -f $MUNGED_OURS ]]; then
        pid=$(tr -dc '0-9' <"$MUNGED_OURS")
        if [[ -n $pid && $(cat "/proc/$pid/comm" 2>/dev/null) == munged ]]; then
            log "stopping munged ($pid)"
            stop_pid "$pid" munged || rc=1
        fi
        rm -f "$MUNGED_OURS"
    fi
    if conf_is_ours; then
        if [[ -n $(foreign_daemons) ]]; then
            log "other SLURM daemons still run ($(foreign_daemons | tr '\n' ' ')); leaving $CONF in place"
        elif [[ -f $BACKUP ]]; then
            log "restoring $CONF from $BACKUP"
            mv -f "$BACKUP" "$CONF"
        else
            log "removing $CONF"
            rm -f "$CONF"
        fi
    fi
    if pgrep -x slurmstepd >/dev/null; then
        log "warning: slurmstepd still running: $(pgrep -x slurmstepd | tr '\n' ' ')"
    fi
    ((rc == 0)) && log "down"
    return $rc
}

do_status() {
    local ctld slurmd
    ctld=$(pid_alive "$CTLD_PID" slurmctld || true)
    slurmd=$(pid_alive "$SLURMD_PID" slurmd || true)
    echo "slurmctld: ${ctld:-not running}  slurmd: ${slurmd:-not running}  state: $STATE_DIR"
    if [[ -z $ctld ]]; then
        return 1
    fi
    timeout 5 sinfo || return 1
    timeout 5 squeue || return 1
}

case $ACTION in
    up) do_up ;;
    down) do_down ;;
    status) do_status ;;
    *) usage ;;
esac
