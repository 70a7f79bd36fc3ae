#!/usr/bin/env bash
# `vmt dataset` on a real Slurm cluster: installs Slurm and munge from the Debian packages when
# they are missing, starts a single-node cluster on localhost (its own munged, slurmctld and
# slurmd on free ports, state in a temporary folder; no systemd, no cgroups), and checks:
#
# 1. the array script `vmt dataset --emit slurm` writes, submitted as its comments say
#    (`bash FILE`: the array of 4 shards x 5 runs, then the merge job after it), gives a folder
#    byte-identical to a one-machine run of the same scenario, seed and count (manifest CSV and
#    Parquet, dataset.json, every run's files);
# 2. faults, on the same dataset split into 2 shards of 10 runs: one running task's vmt killed
#    with kill -9 and the task requeued, the other task requeued while it runs (as when its node
#    is lost): both complete their shards without redoing or duplicating a run, and the merge
#    is again byte-identical to the one-machine run.
#
# Usage: .ci/slurm-dataset.sh PATH/TO/vmt   (CI runs it from .ci/run)
# It needs root (apt-get, munged as the munge user, slurmd): run as another user, it runs itself
# again under `sudo -n`, and fails, saying so, when there is no password-less sudo; it fails
# likewise when Slurm is not installed and apt-get is missing or cannot install it. It never
# skips. Safe to run on a machine of one's own: everything lives in a temporary folder, the
# daemons are ours (stopped by their pid files on exit) and the ports are free ones. On a
# failure it prints the daemons' logs and the tasks' output. KEEP=1 keeps the temporary folder.
set -euo pipefail

vmt=$(realpath "${1:?usage: $0 PATH/TO/vmt}")
repo=$(cd "$(dirname "$0")/.." && pwd)
[ -x "$vmt" ] || { echo "slurm-dataset: FAIL: $vmt is not an executable vmt" >&2; exit 2; }
if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
        echo "slurm-dataset: not root: running again under sudo" >&2
        exec sudo -n env KEEP="${KEEP:-0}" bash "$repo/.ci/slurm-dataset.sh" "$vmt"
    fi
    echo "slurm-dataset: FAIL: the real-Slurm test needs root (it installs slurm-wlm and munge" \
        "with apt-get and starts munged and slurmd) and $(id -un) is not root and has no" \
        "password-less sudo: run .ci/run as root or give this user sudo without a password" >&2
    exit 2
fi

work=$(mktemp -d /tmp/vmt-slurm.XXXXXX)
chmod 755 "$work"
jobs=()

log() { echo "slurm-dataset: $*" >&2; }

dump_logs() {
    for f in "$work"/munge/munged.log "$work"/slurmctld.log "$work"/slurmd.log "$work"/run/*.out; do
        [ -f "$f" ] || continue
        echo "===== $f (last 60 lines)"
        tail -n 60 "$f"
    done
}

stop_pid_file() {
    local f=$1
    [ -f "$f" ] || return 0
    local pid
    pid=$(cat "$f")
    kill "$pid" 2>/dev/null || return 0
    for _ in $(seq 50); do
        kill -0 "$pid" 2>/dev/null || return 0
        sleep 0.1
    done
    kill -9 "$pid" 2>/dev/null || true
}

cleanup() {
    local rc=$?
    set +e
    if [ "$rc" != 0 ]; then
        log "FAILED (exit $rc); the daemons' logs and the tasks' output follow"
        dump_logs
    fi
    [ "${#jobs[@]}" -gt 0 ] && scancel "${jobs[@]}" 2>/dev/null
    stop_pid_file "$work/slurmd.pid"
    stop_pid_file "$work/slurmctld.pid"
    stop_pid_file "$work/munge/munged.pid"
    if [ "${KEEP:-0}" = 1 ]; then log "kept $work"; else rm -rf "$work"; fi
    exit "$rc"
}
trap cleanup EXIT

fail() { log "FAIL: $*"; exit 1; }

# --- Slurm and munge from the Debian packages -------------------------------------------------
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    command -v apt-get >/dev/null ||
        fail "Slurm and munge are not installed and there is no apt-get to install them (a Debian-like machine is needed: slurm-wlm, munge)"
    log "installing slurm-wlm and munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq || fail "apt-get update failed (no network, or no package source?)"
    apt-get install -y -qq slurm-wlm munge >/dev/null || fail "apt-get install slurm-wlm munge failed"
    command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v munged >/dev/null ||
        fail "slurm-wlm and munge installed, yet slurmctld, slurmd or munged is not on the PATH ($PATH)"
fi
[ -f /etc/munge/munge.key ] || runuser -u munge -- mungekey --create

# --- munge, on a socket of its own --------------------------------------------------------------
install -d -o munge -g munge -m 755 "$work/munge"
socket="$work/munge/munge.socket"
runuser -u munge -- munged --socket="$socket" --pid-file="$work/munge/munged.pid" \
    --log-file="$work/munge/munged.log" --seed-file="$work/munge/munged.seed"
for _ in $(seq 50); do [ -S "$socket" ] && break; sleep 0.1; done
munge -n -S "$socket" | unmunge -S "$socket" >/dev/null || fail "munge does not authenticate"

# --- a single-node cluster on localhost ---------------------------------------------------------
read -r ctld_port node_port < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
host=$(hostname -s)
cpus=$(nproc)
mkdir -p "$work/state" "$work/spool" "$work/run"
export SLURM_CONF="$work/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=vmtci
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$node_port
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket,cred_expire=10
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MailProg=/bin/true
MinJobAge=300
SchedulerParameters=sched_interval=2
ReturnToService=2
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -c
slurmd
state=
for _ in $(seq 100); do
    state=$(sinfo -h -o %T 2>/dev/null || true)
    [ "$state" = idle ] && break
    sleep 0.2
done
[ "$state" = idle ] || fail "the node is not idle (sinfo: '$state')"
log "cluster up: $host, $cpus CPUs, slurmctld :$ctld_port, slurmd :$node_port"

# --- the dataset --------------------------------------------------------------------------------
cd "$work/run"
# The dataset scenario with a 50 mm circle, as the dataset tests use (a run takes less time).
sed 's/^radius_mm = 100.0/radius_mm = 50.0/' "$repo/scenarios/dataset_xy.toml" >ds.toml
grep -q '^radius_mm = 50.0' ds.toml || fail "the dataset scenario has no 'radius_mm = 100.0' to shorten"
count=20
shards=4

# The state of job $1 (COMPLETED, FAILED, RUNNING, ...; one line per array task).
job_states() { squeue -h -t all -j "$1" -o %T 2>/dev/null || true; }

# Waits until job $1 (all its tasks) has ended; fails after $2 seconds.
wait_ended() {
    local waited=0
    while job_states "$1" | grep -qvE '^(COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|PREEMPTED|BOOT_FAIL|DEADLINE)$'; do
        sleep 1
        waited=$((waited + 1))
        [ "$waited" -lt "$2" ] || fail "job $1 still not ended after $2 s: $(job_states "$1" | sort | uniq -c | tr '\n' ' ')"
    done
}

# Compares dataset folders $1 and $2 byte for byte (every file but the lock files), naming
# the manifest's files first.
same_dataset() {
    for f in dataset.json manifest.csv manifest.parquet; do
        cmp "$1/$f" "$2/$f" || fail "$2/$f differs from the one-machine run's"
    done
    diff -r --exclude=.lock "$1" "$2" >/dev/null || { diff -rq --exclude=.lock "$1" "$2" || true; fail "$2 differs from the one-machine run $1"; }
    local runs
    runs=$(find "$2/runs" -mindepth 1 -maxdepth 1 | wc -l)
    [ "$runs" = "$count" ] || fail "$2/runs holds $runs entries, not the $count runs"
}

log "one-machine run: $count runs"
"$vmt" dataset --scenario ds.toml --count "$count" --seed 7 --out one --quiet

# --- 1. the emitted array script, submitted as its comments say ---------------------------------
"$vmt" dataset --scenario ds.toml --count "$count" --seed 7 --out shared --emit slurm \
    --shards "$shards" --max-parallel 2 >array.sbatch
grep -q "^#SBATCH --array=0-$((shards - 1))%2$" array.sbatch || fail "array.sbatch has no --array=0-$((shards - 1))%2"
submitted=$(bash array.sbatch)
log "$submitted"
array=$(sed -n 's/^submitted array job \([0-9]*\) .*/\1/p' <<<"$submitted")
merge=$(sed -n 's/.* merge job \([0-9]*\)$/\1/p' <<<"$submitted")
[ -n "$array" ] && [ -n "$merge" ] || fail "no job ids in: $submitted"
jobs+=("$array" "$merge")
wait_ended "$array" 600
wait_ended "$merge" 300
[ "$(job_states "$array" | sort -u)" = COMPLETED ] || fail "array tasks: $(job_states "$array" | tr '\n' ' ')"
[ "$(job_states "$merge")" = COMPLETED ] || fail "merge job: $(job_states "$merge")"
for k in $(seq 0 $((shards - 1))); do
    grep -q "shard $k/$shards from SLURM_ARRAY_TASK_ID=$k" "vmt-dataset-${array}_$k.out" ||
        fail "task $k does not say which shard it took from the environment"
done
same_dataset one shared
log "1. merged $shards-shard array == one-machine run (manifest.csv, manifest.parquet, dataset.json, $count runs)"

# --- 2. faults: kill -9 of a running task's vmt, and a requeue while a task runs -----------------
# Another split of the same dataset, tasks of 1 CPU, both at once: 10 runs each, some seconds.
fshards=2
"$vmt" dataset --scenario ds.toml --count "$count" --seed 7 --out faults --emit slurm \
    --shards "$fshards" --max-parallel 2 >faults.sbatch
faults=$(sbatch --parsable faults.sbatch)
faults=${faults%%;*}
jobs+=("$faults")

# The pid of the vmt of task $1 of the fault array, once it runs (its environment says which).
task_pid() {
    local exe p env
    for exe in $(find /proc -mindepth 2 -maxdepth 2 -name exe -lname "$vmt" 2>/dev/null); do
        p=${exe%/exe}
        env=$(tr '\0' '\n' <"$p/environ" 2>/dev/null) || continue
        if grep -qx "SLURM_ARRAY_JOB_ID=$faults" <<<"$env" && grep -qx "SLURM_ARRAY_TASK_ID=$1" <<<"$env"; then
            echo "${p#/proc/}"
            return 0
        fi
    done
    return 1
}

# Complete runs of shard $1 in the fault folder.
shard_runs() {
    local n=0 d
    for d in faults/runs/[0-9]*; do
        [ -f "$d/labels.json" ] || continue
        [ $((10#$(basename "$d") % fshards)) = "$1" ] && n=$((n + 1))
    done
    echo "$n"
}

# Waits until task $1 runs and has finished at least one run of its shard, but not all; prints
# its vmt's pid (found once, then only the runs are watched: a scan of /proc is slow).
caught() {
    local pid= n
    for _ in $(seq 2400); do
        pid=$(task_pid "$1") && break
        sleep 0.05
    done
    [ -n "$pid" ] || fail "task $1 never ran"
    for _ in $(seq 2400); do
        n=$(shard_runs "$1")
        if [ "$n" -ge 1 ]; then
            [ "$n" -lt $((count / fshards)) ] || fail "task $1 finished before it was caught"
            echo "$pid"
            return 0
        fi
        sleep 0.02
    done
    fail "task $1 made no run"
}

pid=$(caught 0)
done_before=$(shard_runs 0)
kill -9 "$pid"
log "2. killed task ${faults}_0 (vmt pid $pid, kill -9) after $done_before of its runs"
for _ in $(seq 100); do
    job_states "${faults}_0" | grep -qE '^(FAILED|COMPLETED)$' && break
    sleep 0.2
done
[ "$(job_states "${faults}_0")" = FAILED ] || fail "task ${faults}_0 killed is $(job_states "${faults}_0"), not FAILED"
scontrol requeue "${faults}_0"

caught 1 >/dev/null
scontrol requeue "${faults}_1"
log "2. requeued task ${faults}_1 while it ran, after $(shard_runs 1) of its runs"

wait_ended "$faults" 600
[ "$(job_states "$faults" | sort -u)" = COMPLETED ] || fail "fault array tasks: $(job_states "$faults" | tr '\n' ' ')"
for k in 0 1; do
    out="vmt-dataset-${faults}_$k.out"
    # The rerun's line: `N runs simulated ..., M already complete`: M + N is the shard, M > 0.
    line=$(grep 'runs simulated' "$out" | tail -n 1)
    again=$(sed -n 's/.*, \([0-9]*\) already complete.*/\1/p' <<<"$line")
    made=$(sed -n 's/^\([0-9]*\) runs simulated.*/\1/p' <<<"$line")
    [ -n "$again" ] && [ "$again" -ge 1 ] || fail "task $k's rerun redid its finished runs: $line"
    [ $((again + made)) = $((count / fshards)) ] || fail "task $k's rerun: $line"
done
leftovers=$(find faults -name '.tmp-*' | wc -l)
[ "$leftovers" = 0 ] || fail "$leftovers half-written files or folders left in faults/"
"$vmt" dataset merge faults
[ "$(tail -n +2 faults/manifest.csv | cut -d, -f1 | sort -u | wc -l)" = "$count" ] ||
    fail "faults/manifest.csv does not list each of the $count runs once"
same_dataset one faults
log "2. after kill -9 + requeue and a requeue while running: nothing lost or redone, merge == one-machine run"
log "passed"
