#!/usr/bin/env bash
# scripts/slurm on a real one-node Slurm cluster (slurm-wlm and munge from Debian 12), started
# as root in a temporary folder with its own slurm.conf, free ports, spool and munge key, and
# stopped at the end whatever happens. Requires, byte for byte against an unsharded generate:
#  1. scripts/slurm/submit with 3 shards, one array task requeued by Slurm part-way through
#     (as on preemption or a node failure): the task resumes and the merge job runs by itself;
#  2. a task's chromasim killed with SIGKILL part-way through, its task failed: `scontrol
#     requeue` resumes it, and the merge (left pending by afterok) is run again by hand.
# Also requires generate.sbatch to refuse to run outside a job array or in one not from 1.
# Exits 77 (SKIPPED in CTest) with the reason when it is not root, the packages are missing
# or the daemons do not start; never a pass in those cases.
#   tests/scripts/test_slurm.sh CHROMASIM_EXE SOURCE_DIR
set -euo pipefail
exe=$1
slurm=$2/scripts/slurm
skip() { echo "SKIPPED: $*"; exit 77; }
[[ $(id -u) == 0 ]] || skip "the test cluster's daemons run as root, and this is uid $(id -u)"
for tool in munged munge slurmctld slurmd sbatch scontrol scancel sinfo; do
    command -v "$tool" >/dev/null ||
        skip "no $tool: scripts/install-deps installs slurm-wlm and munge"
done

work=$(mktemp -d "${TMPDIR:-/tmp}/chromasim_test_slurm.XXXXXX")
chmod 755 "$work" # munge's socket folder must be reachable by every user
stop_daemons() {
    local pidfile pid
    for pidfile in "$work"/slurmd.pid "$work"/slurmctld.pid "$work"/munge/munged.pid; do
        [[ -s $pidfile ]] || continue
        pid=$(<"$pidfile")
        kill "$pid" 2>/dev/null || continue
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
    done
}
trap 'stop_daemons; rm -rf "$work"' EXIT
trap 'exit 1' INT TERM HUP
cd "$work"
logs() { for f in "$work"/log/*.log; do echo "== $f"; tail -n 20 "$f"; done >&2; }
fail() { echo "FAIL: $*" >&2; logs; exit 1; }

# --- the cluster ------------------------------------------------------------------------------
mkdir -p munge spool/ctld spool/d log
chmod 700 munge
head -c 1024 /dev/urandom >munge/munge.key
chmod 400 munge/munge.key
munged --force --socket="$work/munge/socket" --key-file="$work/munge/munge.key" \
    --pid-file="$work/munge/munged.pid" --log-file="$work/log/munged.log" \
    --seed-file="$work/munge/seed" || skip "munged did not start: $(tail -n 3 log/munged.log)"
read -r ctld_port slurmd_port < <(python3 -c '
import socket
ss = [socket.socket() for _ in range(2)]
for s in ss: s.bind(("127.0.0.1", 0))
print(*(s.getsockname()[1] for s in ss))')
node=$(hostname -s)
# cred_expire: a requeued job waits this long before it starts again (120 s by default); a
# start forced sooner meets the killed run's revoked credential and fails.
cat >slurm.conf <<CONF
ClusterName=chromasimtest
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$work/munge/socket,cred_expire=10
CredType=cred/munge
StateSaveLocation=$work/spool/ctld
SlurmdSpoolDir=$work/spool/d
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
ProctrackType=proctrack/pgid
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
KillWait=5
NodeName=$node NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$work/slurm.conf
slurmctld -f "$SLURM_CONF" || skip "slurmctld did not start: $(tail -n 3 log/slurmctld.log)"
slurmd -f "$SLURM_CONF" || skip "slurmd did not start: $(tail -n 3 log/slurmd.log)"
for _ in $(seq 60); do
    [[ $(sinfo -h -o %T 2>/dev/null) == idle ]] && break
    sleep 0.5
done
[[ $(sinfo -h -o %T 2>/dev/null) == idle ]] ||
    skip "the node is not idle 30 s after slurmd started ($(sinfo -h -o %T 2>&1)):" \
        "$(tail -n 3 log/slurmd.log)"
echo "cluster: node $node, $(nproc) CPUs, slurmctld :$ctld_port, slurmd :$slurmd_port"

# --- the dataset ------------------------------------------------------------------------------
# Six small trials of 12 frames, both fingers, every output: two per shard, so that a task can
# be stopped with one trial kept and the next in progress.
cat >spec.yaml <<'SPEC'
name: slurm
seed: 3
sensor: {mesh_level: coarse, element_order: 1}
render: {width_px: 32, height_px: 32, samples_per_pixel: 1, integrator: preview}
objects: [{name: flat, shape: flat}, {name: curved, shape: sphere, radius_mm: 45}]
friction: [{name: m, mu: 0.8}]
sampling: {method: random, trials: 6}
protocol: {frame_rate_Hz: 4, grip_N: 1.0, grasp_s: 1, hold_s: 1, load_rate_N_per_s: 0.6,
           target_load_N: 0.6, slip_frames: 0}
splits: [{name: train, fraction: 0.5}, {name: test, fraction: 0.5}]
outputs: {images: true, exr: true, labels: true, markers: true, strain: true}
SPEC
export CHROMASIM=$exe CHROMASIM_CACHE_DIR=$work/cache CHROMASIM_GENERATE_ARGS=-q
"$exe" --threads 1 generate spec.yaml -q -o ref # also fills the mechanics cache

if SLURM_ARRAY_TASK_ID= bash "$slurm/generate.sbatch" spec.yaml bad 2>/dev/null; then
    fail "generate.sbatch ran outside a job array"
fi
if SLURM_ARRAY_TASK_ID=2 SLURM_ARRAY_TASK_MIN=2 SLURM_ARRAY_TASK_MAX=3 SLURM_ARRAY_TASK_COUNT=2 \
    bash "$slurm/generate.sbatch" spec.yaml bad 2>/dev/null; then
    fail "generate.sbatch ran in an array 2-3"
fi

state() { scontrol show job "$1" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -n 1; }
restarts() { scontrol show job "$1" | sed -n 's/.*Restarts=\([0-9]*\).*/\1/p' | head -n 1; }
wait_for() { # JOB STATE... : waits up to 300 s for JOB to reach one of the states
    local job=$1 s
    shift
    for _ in $(seq 1500); do
        s=$(state "$job")
        for want in "$@"; do [[ $s == "$want" ]] && return 0; done
        sleep 0.2
    done
    fail "job $job is $s after 300 s, not ${*}"
}
trials_done() { find "$1.partial/_progress" -name 'trial_*.json' 2>/dev/null | wc -l; }
wait_mid_part() { # PART: waits until PART has one complete trial and the next in progress
    for _ in $(seq 3000); do
        [[ $(trials_done "$1") -ge 1 ]] && break
        sleep 0.1
    done
    [[ $(trials_done "$1") == 1 ]] || fail "$1 was not caught between its trials"
}
submit() { # OUT: scripts/slurm/submit, 3 shards of one CPU; sets $array and $merge
    local printed
    printed=$("$slurm/submit" spec.yaml "$1" 3 --cpus-per-task=1)
    echo "$printed"
    array=$(sed -n 's/^array job \([0-9]*\) .*/\1/p' <<<"$printed")
    merge=$(sed -n 's/^merge job \([0-9]*\) .*/\1/p' <<<"$printed")
    [[ -n $array && -n $merge ]] || fail "submit printed no job ids"
}
same_bytes() { # OUT
    diff -r ref "$1/dataset" >&2 || fail "$1/dataset differs from the unsharded dataset"
    cmp ref/manifest.json "$1/dataset/manifest.json"
}

# 1. Requeued by Slurm part-way through: the merge follows by itself.
submit preempted
wait_mid_part preempted/part_2
scontrol requeue "${array}_2"
wait_for "$merge" COMPLETED FAILED CANCELLED
[[ $(state "$merge") == COMPLETED ]] || fail "merge job $merge is $(state "$merge")"
[[ $(restarts "${array}_2") == 1 ]] || fail "task ${array}_2 was not requeued"
same_bytes preempted
echo "ok: 3 array tasks, one requeued mid-run, + merge = the unsharded dataset, byte for byte"

# 2. SIGKILL part-way through: the task fails, is requeued by hand and resumes.
submit killed
wait_mid_part killed/part_3
pid=$(pgrep -f -- "-o killed/part_3 --shard 3/3") || fail "no chromasim process of task 3"
kill -9 "$pid"
wait_for "${array}_3" FAILED
[[ $(state "$merge") == PENDING ]] || fail "merge job $merge ran after a task failed"
scontrol requeue "${array}_3"
wait_for "${array}_3" COMPLETED
scancel "$merge" # afterok can no longer be met: submit the merge again
sbatch --wait --output="$work/log/merge-again.log" "$slurm/merge.sbatch" killed >/dev/null ||
    fail "the merge run again failed: $(cat "$work/log/merge-again.log")"
same_bytes killed
echo "ok: a task killed with SIGKILL mid-run, requeued, + merge = the unsharded dataset"
