#!/bin/bash
# Renders a frame as a SLURM job array of PARTS tasks and merges the parts when all succeed.
#   SCENE=scene.pbrt PARTS=16 OUT=/shared/run1 INTEGRATOR=ratio deploy/slurm/submit-frame.sh
#   SCENE=scene.pbrt PARTS=16 SPLIT=samples SPP=256 OUT=/shared/ref deploy/slurm/submit-frame.sh
# (the second: a 4096-spp progressive reference in 16 jobs of 256 samples). See frame.sbatch for
# the variables; SBATCH_ARGS are passed to both sbatch calls (e.g. "--partition=cpu").
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
: "${SCENE:?set SCENE}" "${PARTS:?set PARTS}" "${OUT:?set OUT}"
export SCENE PARTS OUT SPLIT SPP INTEGRATOR RENDER_ARGS MERGE_ARGS IMAGE PENUMBRA
mkdir -p "$OUT"
# shellcheck disable=SC2206
sb=(${SBATCH_ARGS:-})
array=$(sbatch --parsable --export=ALL "${sb[@]}" --chdir="$OUT" --array="0-$((PARTS - 1))" "$here/frame.sbatch")
array=${array%%;*}
merge=$(sbatch --parsable --export=ALL "${sb[@]}" --chdir="$OUT" --dependency="afterok:$array" "$here/merge.sbatch")
echo "frame: array job $array ($PARTS tasks), merge job ${merge%%;*} -> $OUT/${IMAGE:-frame.exr}"
