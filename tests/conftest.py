"""Shared test fixtures: the shared reference folder and a CLI runner."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent


def shared_dir() -> Path | None:
    """The project's shared folder (fixtures, thesis): $MECHANISM_SHARED or ../shared."""
    candidates = [os.environ.get("MECHANISM_SHARED"), REPO_ROOT.parent / "shared"]
    for candidate in candidates:
        if candidate and Path(candidate, "cad-exports").is_dir():
            return Path(candidate)
    return None


@pytest.fixture
def shared() -> Path:
    path = shared_dir()
    if path is None:
        pytest.skip("the shared folder (../shared or $MECHANISM_SHARED) with the CAD export fixtures is not present")
    return path


class CliResult:
    def __init__(self, proc: subprocess.CompletedProcess):
        self.returncode = proc.returncode
        self.stdout = proc.stdout
        self.stderr = proc.stderr

    def assert_bad_input(self) -> str:
        """Exit 2, exactly one stderr line starting with 'error:', no traceback."""
        lines = [line for line in self.stderr.splitlines() if line.strip()]
        error_lines = [line for line in lines if line.startswith("error:")]
        assert self.returncode == 2, (self.returncode, self.stderr)
        assert "Traceback" not in self.stderr, self.stderr
        assert len(error_lines) == 1, self.stderr
        return error_lines[0]


def run_cli(*args: str, timeout: float = 600, cwd: Path | None = None, env: dict | None = None) -> CliResult:
    """Run ``python -m mechanism ARGS`` in a fresh process, as a user would."""
    full_env = dict(os.environ)
    full_env.pop("MECHANISM_DEBUG", None)
    full_env.setdefault("MPLBACKEND", "Agg")
    if env:
        full_env.update(env)
    proc = subprocess.run(
        [sys.executable, "-m", "mechanism", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=cwd or REPO_ROOT,
        env=full_env,
    )
    return CliResult(proc)


@pytest.fixture
def cli():
    return run_cli
