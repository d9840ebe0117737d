#!/usr/bin/env bash
# Fuzz smoke run: each target for SECONDS (default 60) from its seeds, with the nightly
# toolchain. Uses cargo-fuzz when installed, else the same instrumentation flags by hand
# (libFuzzer from libfuzzer-sys, sanitizer coverage; no ASan: the code is safe Rust).
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
TARGET=x86_64-unknown-linux-gnu
if cargo +nightly fuzz --version >/dev/null 2>&1; then
  build() { cargo +nightly fuzz build -O "$1"; }
  BIN=target/$TARGET/release
else
  export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks"
  build() { cargo +nightly build --release --target "$TARGET" --bin "$1"; }
  BIN=target/$TARGET/release
fi
for t in parse scene_build; do
  build "$t"
  limit=()
  if [[ "$SECONDS_PER_TARGET" == ci ]]; then
    # Seed 1, fixed counts: parse 300,000 inputs (12 s here), scene_build 2,500 (15 s).
    if [[ "$t" == parse ]]; then limit=(-seed=1 -runs=300000); else limit=(-seed=1 -runs=2500); fi
  elif [[ "$SECONDS_PER_TARGET" != 0 ]]; then
    limit=(-max_total_time="$SECONDS_PER_TARGET")
  fi
  "$BIN/$t" "corpus/$t" -artifact_prefix=artifacts/ -rss_limit_mb=4096 -timeout=30 -max_len=65536 "${limit[@]}" "$@"
done
