"""Shared fixtures: the repository's paths and the CLI binary."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    """The `mbsolve` binary of this checkout (built once if missing)."""
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    exe = target / "release" / "mbsolve"
    if not exe.exists():
        subprocess.run(
            ["cargo", "build", "--release", "--bin", "mbsolve"], cwd=ROOT, check=True
        )
    return exe
