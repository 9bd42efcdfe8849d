#!/usr/bin/env bash
# A throwaway single-node Slurm cluster on localhost, for trying gdr submit
# without a cluster and for tests/slurm.sh. munged, slurmctld -D and
# slurmd -D run without systemd from one folder that holds their slurm.conf,
# munge key, state, spool and logs; they listen on free ports on 127.0.0.1,
# beside any Slurm the machine runs. Needs root (slurmd starts jobs as their
# user) and the Debian packages slurm-wlm and munge
# (scripts/install-deps.sh installs them).
#
#   bash scripts/local-slurm.sh start DIR   # DIR must not exist; prints the SLURM_CONF to export
#   bash scripts/local-slurm.sh stop DIR    # cancels its jobs, stops its daemons by pid, removes DIR
#
# Sourced, it defines local_slurm_missing, local_slurm_start DIR and
# local_slurm_stop DIR (which tests/slurm.sh uses).

# The first program the cluster needs that is not installed ("" if none).
local_slurm_missing() {
    local p
    for p in munged mungekey slurmctld slurmd sbatch squeue scancel sinfo; do
        PATH="$PATH:/usr/sbin:/sbin" command -v "$p" > /dev/null || { echo "$p"; return; }
    done
}

# Starts the cluster in DIR (created, or empty) and exports SLURM_CONF=DIR/slurm.conf.
# The daemons' pids go to DIR/pids. Returns 1, with the reason on stderr, if it does not come up.
local_slurm_start() {
    local dir=$1 detach=${2:-}
    export PATH="$PATH:/usr/sbin:/sbin"
    mkdir -p "$dir" && dir=$(cd "$dir" && pwd) || return 1
    # munged wants every folder on the way to its socket searchable by all, and its key private.
    chmod 755 "$dir"
    mkdir -p "$dir/munge" "$dir/run" "$dir/state" "$dir/spool" "$dir/log"
    chmod 700 "$dir/munge"
    : > "$dir/pids"
    local run=()
    [ -n "$detach" ] && run=(setsid)  # started from a command that exits: not in its session
    mungekey --create --keyfile="$dir/munge/munge.key" > /dev/null || { echo "mungekey failed" >&2; return 1; }
    "${run[@]}" munged --foreground --key-file="$dir/munge/munge.key" --socket="$dir/run/munge.socket" \
        --pid-file="$dir/run/munged.pid" --seed-file="$dir/munge/seed" --log-file="$dir/log/munged.log" \
        > "$dir/log/munged.out" 2>&1 < /dev/null &
    echo $! >> "$dir/pids"
    local _
    for _ in $(seq 100); do [ -S "$dir/run/munge.socket" ] && break; sleep 0.1; done
    [ -S "$dir/run/munge.socket" ] || { echo "munged did not start: $(cat "$dir/log/munged.out")" >&2; return 1; }

    local host ctld_port slurmd_port node
    host=$(hostname -s)
    ctld_port=$(_local_slurm_free_port $((20000 + RANDOM % 20000)))
    slurmd_port=$(_local_slurm_free_port $((ctld_port + 1)))
    node=$(slurmd -C | head -n 1)  # NodeName=HOST CPUs=... as this machine has them
    export SLURM_CONF="$dir/slurm.conf"
    cat > "$SLURM_CONF" <<EOF
# A single-node cluster on localhost, written by gdr's scripts/local-slurm.sh.
ClusterName=gdrlocal
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/run/munge.socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
# No cgroups, no accounting database: processes are tracked by parentage.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
MailProg=/bin/true
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
KillWait=30
MinJobAge=300
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    "${run[@]}" slurmctld -D -f "$SLURM_CONF" > "$dir/log/slurmctld.out" 2>&1 < /dev/null &
    echo $! >> "$dir/pids"
    for _ in $(seq 100); do sinfo -h > /dev/null 2>&1 && break; sleep 0.1; done
    "${run[@]}" slurmd -D -f "$SLURM_CONF" -N "$host" > "$dir/log/slurmd.out" 2>&1 < /dev/null &
    echo $! >> "$dir/pids"
    for _ in $(seq 200); do [ "$(sinfo -h -N -o %t 2>/dev/null)" = idle ] && break; sleep 0.1; done
    if [ "$(sinfo -h -N -o %t 2>/dev/null)" != idle ]; then
        echo "the node did not come up: $(sinfo -N 2>&1)" >&2
        tail -n 5 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" >&2 2>/dev/null
        return 1
    fi
}

# Cancels the jobs of the cluster in DIR, stops the daemons in DIR/pids (newest first) and removes DIR.
local_slurm_stop() {
    local dir=$1 pid _
    [ -d "$dir" ] || return 0
    if [ -f "$dir/slurm.conf" ] && [ "$(wc -l < "$dir/pids" 2>/dev/null)" -ge 3 ]; then
        # Only this cluster's jobs: its own slurm.conf. No task may outlive its slurmd.
        SLURM_CONF="$dir/slurm.conf" scancel --user="$(id -un)" 2>/dev/null
        for _ in $(seq 40); do [ -z "$(SLURM_CONF="$dir/slurm.conf" squeue -h -o %i 2>/dev/null)" ] && break; sleep 0.25; done
    fi
    if [ -f "$dir/pids" ]; then
        local pids=()
        mapfile -t pids < <(tac "$dir/pids")
        for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null; done
        for pid in "${pids[@]}"; do
            for _ in $(seq 40); do _local_slurm_gone "$pid" && break; sleep 0.25; done
            _local_slurm_gone "$pid" || kill -KILL "$pid" 2>/dev/null
            wait "$pid" 2>/dev/null  # reaps it where it is this shell's child
        done
    fi
    rm -rf "$dir"
}

# True once process $1 has exited (a zombie waiting for its parent counts as gone).
_local_slurm_gone() {
    [ -r "/proc/$1/stat" ] || return 0
    [ "$(awk '{print $3}' "/proc/$1/stat" 2>/dev/null)" = Z ]
}

# A free TCP port on 127.0.0.1 from $1 upwards.
_local_slurm_free_port() {
    local p=$1
    while (exec 3<> "/dev/tcp/127.0.0.1/$p") 2>/dev/null; do p=$((p + 1)); done
    echo "$p"
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    set -u
    case "${1:-} ${2:+dir}" in
        "start dir")
            [ -e "$2" ] && { echo "local-slurm: $2 exists; give a new folder" >&2; exit 2; }
            missing=$(local_slurm_missing)
            [ -z "$missing" ] || { echo "local-slurm: $missing is not installed (Debian packages slurm-wlm and munge)" >&2; exit 1; }
            [ "$(id -u)" = 0 ] || { echo "local-slurm: needs root to run slurmd" >&2; exit 1; }
            if ! local_slurm_start "$2" detach; then local_slurm_stop "$2"; exit 1; fi
            echo "local-slurm: node $(hostname -s) is up, daemons $(tr '\n' ' ' < "$(dirname "$SLURM_CONF")/pids")"
            printf 'export SLURM_CONF=%q\n' "$SLURM_CONF"
            ;;
        "stop dir") local_slurm_stop "$2" ;;
        *) echo "usage: bash scripts/local-slurm.sh start|stop DIR" >&2; exit 2 ;;
    esac
fi
