#!/usr/bin/env bash
set -euo pipefail
# Test dependencies for penumbra's image cross-checks (run by the CI script, which fails if
# they cannot be installed; idempotent).
# idiff/oiiotool for tests/idiff_crosscheck.rs, and OpenImageIO's Python bindings, which the
# same test uses to read idiff's numbers at full double precision.
command -v idiff >/dev/null 2>&1 || (apt-get update && apt-get install -y openimageio-tools)
python3 -c 'import OpenImageIO' >/dev/null 2>&1 || (apt-get update && apt-get install -y python3-openimageio)
# Embree 3 for the optional ray-query backend (cargo feature `embree`), whose tests CI runs
# beside the README's command.
test -e /usr/include/embree3/rtcore.h || (apt-get update && apt-get install -y libembree-dev)
# Python 3 with venv and pip for the Python package's tests (python/test.sh).
command -v python3 >/dev/null 2>&1 || (apt-get update && apt-get install -y python3)
python3 -c 'import ensurepip, venv' >/dev/null 2>&1 && python3 -m pip --version >/dev/null 2>&1 \
  || (apt-get update && apt-get install -y python3-venv python3-pip)
