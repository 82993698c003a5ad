#!/bin/bash
# Generate a MOE-Touch training set as a Slurm array job, then merge its card.
#
#   sbatch --array=1-8 deploy/slurm-gen-data.sh            # 8 machines
#   sbatch --dependency=afterok:<JOBID> deploy/slurm-merge.sh
#
# Every task runs the same command; `--shard auto/N` takes the task's index from
# SLURM_ARRAY_TASK_ID (0- or 1-based arrays both work: SLURM_ARRAY_TASK_MIN is subtracted).
# The output directory must be on a file system every node sees. A task that is
# requeued skips the shards that already exist, so the job can simply be resubmitted.
#
# Edit the settings below (or export them before sbatch); every task and the merge step must
# use the same values.
#SBATCH --job-name=moe-gen-data
#SBATCH --cpus-per-task=8
#SBATCH --mem=8G
#SBATCH --time=04:00:00
#SBATCH --output=moe-gen-data-%A_%a.log
set -euo pipefail

: "${MOE_DATA_DIR:=$PWD/data/train}"
: "${MOE_TRAJECTORIES:=4000}"
: "${MOE_SEED:=2026}"
: "${MOE_FINGERS:=2}"
: "${MOE_PER_SHARD:=32}"
# Number of tasks: the array's size, unless given.
: "${MOE_MACHINES:=${SLURM_ARRAY_TASK_COUNT:?submit with --array=1-N or set MOE_MACHINES}}"

export RAYON_NUM_THREADS="${SLURM_CPUS_PER_TASK:-1}"
cargo run --release -p moe-touch-cli -- gen-data \
  --out "$MOE_DATA_DIR" \
  --trajectories "$MOE_TRAJECTORIES" \
  --seed "$MOE_SEED" \
  --fingers "$MOE_FINGERS" \
  --trajectories-per-shard "$MOE_PER_SHARD" \
  --shard "auto/$MOE_MACHINES"
