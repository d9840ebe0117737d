#!/bin/sh
# Paired CPU time of `sheared-ao` (A) against `ambientocclusion` with one ray per camera sample
# (B) at the spp where B reaches about A's RMSE, then both RMSEs against pbrt-v3's
# `ambientocclusion` reference (docs/integrators/sheared-ao.md, "Paired CPU time at equal
# error"). farm-bench alternates A and B, so the ratio holds on a machine shared with other work.
# Usage: tools/sheared_ao_equal_error.sh [PENUMBRA] [OUTDIR]   (run from the repository root)
P=${1:-target/release/penumbra}
O=${2:-/tmp/sheared-ao-equal-error}
S=scenes/suite/ao
R=../shared/references/ao
mkdir -p "$O"
while read scene sspp aospp; do
  A="$P render $S/$scene.pbrt -i sheared-ao --spp $sspp --resolution 256x256 --threads 1 -q -o $O/A.$scene.$sspp.exr"
  B="$P render $S/$scene.pbrt -i ambientocclusion --param nsamples=1 --spp $aospp --resolution 256x256 --threads 1 -q -o $O/B.$scene.$aospp.exr"
  echo "== $scene sheared-ao $sspp spp vs ambientocclusion nsamples=1 $aospp spp"
  farm-bench -n 3 --timeout 900 --vs "$B" -- $A
  for f in "$O/A.$scene.$sspp.exr" "$O/B.$scene.$aospp.exr"; do
    echo "$f rmse $($P diff --json --no-flip --channels R,G,B "$f" "$R/$scene.ambientocclusion.exr" |
      python3 -c 'import json,sys; print(json.load(sys.stdin)["mse"] ** 0.5)')"
  done
done <<LIST
blinds 4 78
blinds 8 154
blinds 16 243
spheres-on-plane 4 101
spheres-on-plane 8 210
spheres-on-plane 16 291
LIST
