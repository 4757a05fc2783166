#!/usr/bin/env bash
# Submits a sharded bake of SCENE to Slurm as three dependent jobs, and prints their ids:
#   1. plan:  kage bake SCENE --db DB --dry-run   (the parameter plan, made once, into DB)
#   2. array: N tasks of bake-shard.sbatch          (each bakes 1/N of what DB lacks)
#   3. merge: kage db merge DB SHARDS/shard-*.redb  (after every task succeeded)
#
#   scripts/slurm/submit.sh SCENE N DB [kage bake options…]
#
# DB and the shards' folder (DB's folder/shards) must be on storage every node sees, with
# working file locks (NFSv4, Lustre, BeeGFS, CephFS). KAGE (default: kage on PATH) must run on
# every node. CPUS_PER_TASK (default 1) CPUs per shard; extra sbatch options in SBATCH_ARGS.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
scene=$(realpath "${1:?usage: submit.sh SCENE N DB [options…]}")
n=${2:?usage: submit.sh SCENE N DB [options…]}
db=$(realpath -m "${3:?usage: submit.sh SCENE N DB [options…]}")
shift 3
shards="$(dirname "$db")/shards"
mkdir -p "$shards" "$(dirname "$db")"
kage=$(command -v "${KAGE:-kage}")
cpus=${CPUS_PER_TASK:-1}
export KAGE="$kage" SCENE="$scene" DB="$db" SHARDS="$shards" KAGE_ARGS="$*"
# shellcheck disable=SC2086 # SBATCH_ARGS is a list of options
common=(--parsable --export=ALL --chdir="$(dirname "$db")" ${SBATCH_ARGS:-})
plan=$(sbatch "${common[@]}" --job-name=kage-plan --cpus-per-task="$cpus" \
  --wrap="\"$kage\" bake \"$scene\" $KAGE_ARGS --db \"$db\" --dry-run")
array=$(sbatch "${common[@]}" --dependency="afterok:$plan" --array="0-$((n - 1))" --cpus-per-task="$cpus" \
  "$here/bake-shard.sbatch")
merge=$(sbatch "${common[@]}" --dependency="afterok:$array" --job-name=kage-merge --cpus-per-task=1 \
  --wrap="\"$kage\" db merge \"$db\" \"$shards\"/shard-*.redb")
echo "plan $plan array $array merge $merge"
