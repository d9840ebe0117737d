#!/usr/bin/env bash
# Byte-identity check for refactors: renders every suite and public scene with every
# integrator at a small size and records a hash of each image's pixels (PFM: pixels only,
# no metadata), so two builds can be compared render by render.
#
#   tools/identity.sh BINARY OUTDIR            # render and write OUTDIR/hashes.txt
#   tools/identity.sh --compare A.txt B.txt    # list the renders whose hashes differ
#
# Environment: INTEGRATORS (space-separated; default below), RES (32x32), SPP (4), JOBS (2).
set -euo pipefail
if [[ "${1:-}" == "--compare" ]]; then
  diff <(sort "$2") <(sort "$3") && echo "identical: $(wc -l <"$2") renders" && exit 0
  echo "differences above ('<' $2, '>' $3)"; exit 1
fi
BIN=$(realpath "$1"); OUT=$(realpath -m "$2"); mkdir -p "$OUT"
ROOT=$(cd "$(dirname "$0")/.." && pwd)
INTEGRATORS=${INTEGRATORS:-"directlighting ambientocclusion ltc ratio path whitted"}
RES=${RES:-32x32}; SPP=${SPP:-4}; JOBS=${JOBS:-2}
cd "$ROOT"
# Top-level scenes only: files that declare a camera or WorldBegin.
mapfile -t SCENES < <(grep -rlE '^\s*WorldBegin' scenes/suite scenes/public scenes/relight scenes/default.pbrt 2>/dev/null | sort)
jobs_file=$(mktemp)
for s in "${SCENES[@]}"; do for i in $INTEGRATORS; do echo "$s $i"; done; done >"$jobs_file"
export BIN OUT RES SPP
render_one() {
  local s=$1 i=$2 key; key=$(echo "$s.$i" | tr '/' '_')
  if "$BIN" render "$s" -i "$i" --resolution "$RES" --spp "$SPP" --threads 1 -q \
      -o "$OUT/$key.pfm" >"$OUT/$key.log" 2>&1; then
    echo "$(sha256sum <"$OUT/$key.pfm" | cut -c1-16) $s $i"
  else
    echo "exit$? $s $i"
  fi
  rm -f "$OUT/$key.pfm"
}
export -f render_one
xargs -P "$JOBS" -L 1 bash -c 'render_one "$0" "$1"' <"$jobs_file" | sort -k2 >"$OUT/hashes.txt"
rm -f "$jobs_file"
echo "$(wc -l <"$OUT/hashes.txt") renders -> $OUT/hashes.txt"
