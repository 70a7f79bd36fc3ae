#!/usr/bin/env bash
# Throughput of `vmt dataset` on this machine, in runs per minute, with 1 and 2 workers: a worker
# is one shard process on one thread, as an array task with --cpus-per-task=1 is. Measured from
# the start of the first process to a finished folder (manifest written: for 2 workers, the
# `vmt dataset merge` included), on scenarios/dataset_xy.toml, seed 1. For comparison, one
# process on 2 threads (the laptop command). Both 2-worker folders are checked to be
# byte-identical to the 1-worker one. Beside runs per minute of wall time, runs per CPU-minute
# (user + system time of the processes): on a machine others load, the wall-time figures and
# their ratio fall with the cores they take, while the CPU cost per run says whether sharding
# itself costs anything. It prints the load average before and after.
#
# Usage: scripts/dataset-throughput.sh PATH/TO/vmt [RUNS]   (a release build; RUNS default 300)
set -euo pipefail
vmt=$(realpath "${1:?usage: $0 PATH/TO/vmt [RUNS]}")
runs=${2:-300}
repo=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d /tmp/vmt-throughput.XXXXXX)
trap 'rm -rf "$work"' EXIT
cd "$repo"
ds() { "$vmt" dataset --scenario scenarios/dataset_xy.toml --count "$runs" --seed 1 --quiet "$@" >/dev/null; }
# Runs a phase (a shell function) under bash's `time`: its wall and CPU (user + system, children
# included) seconds into the file $1.
timed() {
    local out=$1
    shift
    local TIMEFORMAT='%R %U %S'
    { time "$@" 2>&1; } 2>"$out"
}
one_worker() { RAYON_NUM_THREADS=1 ds --out "$work/w1"; }
two_workers() {
    RAYON_NUM_THREADS=1 ds --out "$work/w2" --shard 0/2 &
    local p0=$!
    RAYON_NUM_THREADS=1 ds --out "$work/w2" --shard 1/2 &
    local p1=$!
    wait "$p0"
    wait "$p1"
    "$vmt" dataset merge "$work/w2" >/dev/null
}
two_threads() { RAYON_NUM_THREADS=2 ds --out "$work/t2"; }

echo "load before: $(uptime)"
timed "$work/w1.time" one_worker
timed "$work/w2.time" two_workers
timed "$work/t2.time" two_threads
echo "load after: $(uptime)"
for d in w2 t2; do
    diff -r --exclude=.lock "$work/w1" "$work/$d" >/dev/null || { echo "$d differs from the 1-worker folder" >&2; exit 1; }
done
python3 - "$runs" "$(nproc)" "$work"/{w1,w2,t2}.time <<'PY'
import sys
runs, cores = int(sys.argv[1]), sys.argv[2]
(w1, w2, t2) = [list(map(float, open(f).read().split()[-3:])) for f in sys.argv[3:]]
wall = lambda t: runs / t[0] * 60
cpu = lambda t: runs / (t[1] + t[2]) * 60
print(f"{runs} runs of scenarios/dataset_xy.toml on {cores} cores; runs/min of wall time (runs per CPU-minute)")
print(f"1 worker (1 shard, 1 thread):                        {wall(w1):6.0f} ({cpu(w1):.0f})")
print(f"2 workers (shards 0/2, 1/2, 1 thread each; + merge): {wall(w2):6.0f} ({cpu(w2):.0f})")
print(f"scaling, 2 workers / 1 worker: {wall(w2) / wall(w1):.2f} in wall time; CPU per run {cpu(w1) / cpu(w2):.2f} x the 1 worker's")
print(f"1 process on 2 threads (no shards):                  {wall(t2):6.0f} ({cpu(t2):.0f})")
PY
