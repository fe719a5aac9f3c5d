"""Shared fixtures: the repository's paths and the jointplay program built from the same
sources, against which the package is compared."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCENES = ROOT / "data" / "scenes"


@pytest.fixture(scope="session")
def program():
    """Runs the jointplay program (``JOINTPLAY_BIN``, or target/debug/jointplay built here)."""
    exe = os.environ.get("JOINTPLAY_BIN")
    if exe is None:
        subprocess.run(["cargo", "build", "--quiet", "--bin", "jointplay"], cwd=ROOT, check=True)
        exe = str(ROOT / "target" / "debug" / "jointplay")

    def run(*args, check=True):
        return subprocess.run([exe, *map(str, args)], cwd=ROOT, check=check,
                              capture_output=True, text=True)

    return run
