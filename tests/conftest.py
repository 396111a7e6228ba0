"""Shared test fixtures: the shared reference folder and a CLI runner."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers.cli_server import CliServer

REPO_ROOT = Path(__file__).resolve().parent.parent


# -- one Ray test at a time ---------------------------------------------------------------------
# Tests that start or reach a Ray instance carry ``xdist_group("ray")`` and "ray" in their name.
# pytest-xdist's own grouping (``--dist loadgroup``) appends the group to ``item._nodeid``, which
# pytest >= 9.2 no longer reads: the mark alone is silently ignored and two workers would run Ray
# tests at once. The controller sees only node ids, so the name carries the group to it.


def _is_ray_test(nodeid: str) -> bool:
    """The test's name has the word "ray" (or "rays") between underscores; "array" does not count."""
    name = nodeid.rpartition("::")[2].partition("[")[0].lower()
    return bool(re.search(r"(^|_)rays?(_|$)", name))


def pytest_runtest_setup(item):
    if item.get_closest_marker("xdist_group") and not _is_ray_test(item.nodeid):
        pytest.fail(
            f"{item.nodeid}: a test in the Ray group needs 'ray' in its name (the scheduler groups by name)"
        )


try:
    from xdist.scheduler import LoadScopeScheduling
except ImportError:  # without pytest-xdist the tests run one after another anyway
    pass
else:

    class _RayTestsTogether(LoadScopeScheduling):
        """Every test a unit of its own, as ``--dist load``, except the Ray tests: one unit, one worker."""

        def _split_scope(self, nodeid: str) -> str:
            return "ray" if _is_ray_test(nodeid) else nodeid

    def pytest_xdist_make_scheduler(config, log):
        if config.getvalue("dist") in ("load", "loadgroup"):
            return _RayTestsTogether(config, log)
        return None  # another distribution asked for by name: xdist's own


def pytest_configure(config):
    """Each pytest-xdist worker keeps busy its share of the cores, as a run that shares a
    machine should (``MECHANISM_CORES``): a diagnosis on two threads beside another worker's
    only contends (10-12 % more CPU for the same fits). The CLI runs inherit it."""
    from mechanism.files.limits import usable_cores

    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers > 1 and "MECHANISM_CORES" not in os.environ:
        os.environ["MECHANISM_CORES"] = str(max(1, usable_cores() // workers))


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
        pytest.skip(
            "the shared folder (../shared or $MECHANISM_SHARED) with the CAD export fixtures is not present"
        )
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


def run_cli(
    *args: str, timeout: float = 600, cwd: Path | None = None, env: dict | None = None
) -> CliResult:
    """``mechanism ARGS`` in a process of its own, as a user would run it: forked from a server
    that has imported the CLI (:mod:`tests.helpers.cli_server`), or ``python -m mechanism`` in a
    fresh interpreter where the environment differs from the server's."""
    full_env = dict(os.environ)
    full_env.pop("MECHANISM_DEBUG", None)
    full_env.setdefault("MPLBACKEND", "Agg")
    if env:
        full_env.update(env)
    fresh = env or os.environ.get("MECHANISM_TEST_FRESH_CLI")  # the escape hatch: every run fresh
    server = None if fresh else CliServer.get(full_env, REPO_ROOT)
    if server is not None and server.serves(full_env):
        return CliResult(server.run([str(a) for a in args], cwd or REPO_ROOT, full_env, timeout))
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


@pytest.fixture
def cli_here(capfd, monkeypatch):
    """``mechanism ARGS`` run by ``mechanism.cli.main`` in this process, its file descriptors 1 and
    2 captured: the same parser, checks and error lines as a fresh process, without the second
    of interpreter start and imports. For inputs refused before the work starts; what reaches
    the terminal from a whole run (native libraries' text, exit at shutdown) needs ``cli``."""
    from mechanism.cli import main

    monkeypatch.delenv("MECHANISM_DEBUG", raising=False)
    monkeypatch.chdir(REPO_ROOT)

    def run(*args, **_ignored) -> CliResult:
        capfd.readouterr()
        try:
            status = main([str(a) for a in args])
        except SystemExit as exc:  # argparse: --help, or a usage error
            status = exc.code if isinstance(exc.code, int) else 2
        out, err = capfd.readouterr()
        return CliResult(
            subprocess.CompletedProcess(["mechanism", *map(str, args)], status, out, err)
        )

    return run
