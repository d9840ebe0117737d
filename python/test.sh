#!/usr/bin/env bash
# The Python package's tests (issue 40), run by .ci/run and part of the README's test command:
# a virtual environment under target/ (PENUMBRA_VENV to choose another), the test tools, the
# package installed with the README's install command, then its pytest suite.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${PENUMBRA_VENV:-target/py-venv}"
python3 -m venv "$venv"
"$venv/bin/python" -m pip install -q pytest numpy pandas
# The README's install command (maturin comes as the build backend).
"$venv/bin/python" -m pip install -q ./python
# The CLI the tests compare with (already built by `cargo test --workspace --release`).
cargo build --release --quiet --bin penumbra
"$venv/bin/python" -m pytest python/tests -q
