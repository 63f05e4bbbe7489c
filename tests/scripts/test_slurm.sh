#!/usr/bin/env bash
# scripts/slurm without Slurm: runs generate.sbatch's array tasks by hand (the SLURM_* variables
# a job array sets, K = 3, 1, 2 of 3: the order does not matter), a requeued task again, then
# merge.sbatch, and requires the merged dataset to be byte-identical to an unsharded generate
# of the same spec (every file, manifest.json included). Also requires generate.sbatch to refuse
# to run outside a job array and an array that does not start at 1.
#   tests/scripts/test_slurm.sh CHROMASIM_EXE SOURCE_DIR
set -euo pipefail
exe=$1
slurm=$2/scripts/slurm
work=$(mktemp -d "${TMPDIR:-/tmp}/chromasim_test_slurm.XXXXXX")
trap 'rm -rf "$work"' EXIT
cd "$work"
export CHROMASIM=$exe CHROMASIM_CACHE_DIR=$work/cache CHROMASIM_GENERATE_ARGS=-q

# Three tiny trials, both fingers, every output.
cat >spec.yaml <<'SPEC'
name: slurm
seed: 3
sensor: {mesh_level: coarse, element_order: 1}
render: {width_px: 32, height_px: 32, samples_per_pixel: 1}
objects: [{name: flat, shape: flat}, {name: curved, shape: sphere, radius_mm: 45}]
friction: [{name: m, mu: 0.8}]
sampling: {method: random, trials: 3}
protocol: {frame_rate_Hz: 1, grip_N: 1.0, grasp_s: 1, hold_s: 1, load_rate_N_per_s: 0.6,
           target_load_N: 0.6, slip_frames: 0}
splits: [{name: train, fraction: 0.5}, {name: test, fraction: 0.5}]
outputs: {images: true, exr: true, labels: true, markers: true, strain: true}
SPEC

"$exe" --threads 1 generate spec.yaml -q -o ref

task() { # task K: the environment of task K of a 1-3 array
    SLURM_ARRAY_JOB_ID=42 SLURM_ARRAY_TASK_ID=$1 SLURM_ARRAY_TASK_COUNT=3 \
        SLURM_ARRAY_TASK_MIN=1 SLURM_ARRAY_TASK_MAX=3 SLURM_CPUS_PER_TASK=1 \
        bash "$slurm/generate.sbatch" spec.yaml out
}
for k in 3 1 2; do task "$k"; done
task 2 # requeued after it completed: leaves its part as it is
if bash "$slurm/generate.sbatch" spec.yaml out 2>/dev/null; then
    echo "FAIL: generate.sbatch ran outside a job array" >&2
    exit 1
fi
if SLURM_ARRAY_TASK_ID=2 SLURM_ARRAY_TASK_MIN=2 SLURM_ARRAY_TASK_MAX=3 SLURM_ARRAY_TASK_COUNT=2 \
    bash "$slurm/generate.sbatch" spec.yaml out 2>/dev/null; then
    echo "FAIL: generate.sbatch ran in an array 2-3" >&2
    exit 1
fi
for k in 1 2 3; do
    [[ -f out/part_$k/part.json ]] || { echo "FAIL: no out/part_$k/part.json" >&2; exit 1; }
done

bash "$slurm/merge.sbatch" out
if ! diff -r ref out/dataset; then
    echo "FAIL: the merged dataset differs from the unsharded one" >&2
    exit 1
fi
cmp ref/manifest.json out/dataset/manifest.json
echo "ok: 3 array tasks + merge = the unsharded dataset, byte for byte"
