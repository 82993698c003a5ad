#!/bin/bash
# Last step of the Slurm array job in slurm-gen-data.sh: checks that every shard exists and
# writes the data set card. Submit with --dependency=afterok:<array job id>, with the same
# MOE_* settings as the array (MOE_MACHINES is required here: there is no array).
#SBATCH --job-name=moe-gen-merge
#SBATCH --cpus-per-task=1
#SBATCH --mem=2G
#SBATCH --time=00:15:00
#SBATCH --output=moe-gen-merge-%j.log
set -euo pipefail

: "${MOE_DATA_DIR:=$PWD/data/train}"
: "${MOE_TRAJECTORIES:=4000}"
: "${MOE_SEED:=2026}"
: "${MOE_FINGERS:=2}"
: "${MOE_PER_SHARD:=32}"
: "${MOE_MACHINES:?set MOE_MACHINES to the array size}"

cargo run --release -p moe-touch-cli -- gen-data \
  --out "$MOE_DATA_DIR" \
  --trajectories "$MOE_TRAJECTORIES" \
  --seed "$MOE_SEED" \
  --fingers "$MOE_FINGERS" \
  --trajectories-per-shard "$MOE_PER_SHARD" \
  --shard "1/$MOE_MACHINES" \
  --merge
