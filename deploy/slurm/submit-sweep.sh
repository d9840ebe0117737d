#!/bin/bash
# Plans a sweep, runs its items as a SLURM job array and collects them when all succeed:
#   SWEEP_ARGS="scene.pbrt -i directlighting,ltc --reference-spp 4096 --budgets 1,4,16,64" \
#     OUT=/shared/sweep1 deploy/slurm/submit-sweep.sh
# (--plan needs --budgets or --max-budget, not --time-limit.) SBATCH_ARGS as submit-frame.sh.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
: "${SWEEP_ARGS:?set SWEEP_ARGS}" "${OUT:?set OUT}"
PENUMBRA=${PENUMBRA:-penumbra}
export SWEEP_ARGS OUT PENUMBRA
# shellcheck disable=SC2086
n=$("$PENUMBRA" sweep $SWEEP_ARGS -o "$OUT" --plan)
# shellcheck disable=SC2206
sb=(${SBATCH_ARGS:-})
array=$(sbatch --parsable --export=ALL "${sb[@]}" --chdir="$OUT" --array="0-$((n - 1))" "$here/sweep-item.sbatch")
array=${array%%;*}
collect=$(sbatch --parsable --export=ALL "${sb[@]}" --chdir="$OUT" --dependency="afterok:$array" "$here/sweep-collect.sbatch")
echo "sweep: $n items in array job $array, collect job ${collect%%;*} -> $OUT/sweep.csv"
