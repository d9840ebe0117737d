#!/usr/bin/env bash
# Fuzz smoke run: each target for SECONDS (default 60) from its seeds, with the nightly
# toolchain (libFuzzer from libfuzzer-sys; no ASan: the code is safe Rust). The sanitizer
# coverage is set per package in Cargo.toml (penumbra's crates only), so this builds with
# plain cargo rather than cargo-fuzz, whose RUSTFLAGS would instrument every dependency.
# scene_build starts from fuzz/minimised/scene_build (the committed corpus, minimised with
# -set_cover_merge=1) and the seeds seed-build.py makes; runs and findings: fuzz/REPORT.md.
#
#   fuzz/smoke.sh [SECONDS]      # exits non-zero on a crash (the input is in fuzz/artifacts/)
#   fuzz/smoke.sh 0 -runs=10000000   # extra arguments go to libFuzzer
#   fuzz/smoke.sh ci             # CI's run: a fixed seed and input count per target, so
#                                # that a run's outcome does not depend on the machine's speed
set -euo pipefail
cd "$(dirname "$0")"
SECONDS_PER_TARGET=${1:-60}; shift || true
rm -rf corpus/scene_build
python3 seed-build.py >/dev/null
mkdir -p corpus/parse artifacts
cp -n ../scenes/suite/*/*.pbrt corpus/parse/ 2>/dev/null || true
cp minimised/scene_build/* corpus/scene_build/
TARGET=x86_64-unknown-linux-gnu
export RUSTFLAGS="--cfg fuzzing"
build() { cargo +nightly build --release --target "$TARGET" --bin "$1"; }
BIN=target/$TARGET/release
for t in parse scene_build; do
  build "$t"
  limit=()
  if [[ "$SECONDS_PER_TARGET" == ci ]]; then
    # Seed 1, fixed counts: parse 300,000 inputs (12 s here), scene_build 2,500.
    if [[ "$t" == parse ]]; then limit=(-seed=1 -runs=300000); else limit=(-seed=1 -runs=2500); fi
  elif [[ "$SECONDS_PER_TARGET" != 0 ]]; then
    limit=(-max_total_time="$SECONDS_PER_TARGET")
  fi
  "$BIN/$t" "corpus/$t" -artifact_prefix=artifacts/ -rss_limit_mb=4096 -timeout=30 -max_len=65536 "${limit[@]}" "$@"
done
