"""Shared fixtures: the repository root, the CLI binary (built if absent) and a small scene."""

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "suite" / "ltc" / "quad-cube.pbrt"


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def scene_path():
    return SCENE


@pytest.fixture(scope="session")
def cli():
    """The `penumbra` CLI of this checkout (release profile), built when it is missing."""
    exe = Path(os.environ.get("PENUMBRA_CLI", ROOT / "target" / "release" / "penumbra"))
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "penumbra"], cwd=ROOT, check=True)
    return exe
