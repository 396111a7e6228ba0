"""The tests' CLI runner forks its runs from a server that imported the CLI once
(``tests/helpers/cli_server.py``): a forked run must be the run a fresh interpreter gives, the
same output, error line and exit status, also where the run writes files or dies."""

import os
import signal

import pytest

from tests.conftest import run_cli


def _both(monkeypatch, *args, **kwargs):
    forked = run_cli(*args, **kwargs)
    monkeypatch.setenv("MECHANISM_TEST_FRESH_CLI", "1")
    fresh = run_cli(*args, **kwargs)
    monkeypatch.delenv("MECHANISM_TEST_FRESH_CLI")
    return forked, fresh


@pytest.mark.parametrize(
    "args",
    [
        ("--help",),
        ("simulate", "--help"),
        ("simulate", "--machine", "no_such_machine", "--voltage", "12", "--summary"),
        ("simulate", "--reduced", "--duration", "0.5", "--summary"),
        ("identify", "no_such_recording.csv"),
    ],
    ids=["help", "verb-help", "unknown-machine", "no-input", "missing-file"],
)
@pytest.mark.slow
def test_a_forked_run_says_what_a_fresh_interpreter_says(monkeypatch, args):
    forked, fresh = _both(monkeypatch, *args)
    assert (forked.returncode, forked.stdout, forked.stderr) == (
        fresh.returncode,
        fresh.stdout,
        fresh.stderr,
    )


@pytest.mark.slow
def test_a_forked_run_writes_what_a_fresh_one_writes(monkeypatch, tmp_path):
    outputs = []
    for name in ("forked", "fresh"):
        csv = tmp_path / f"{name}.csv"
        args = ("simulate", "--reduced", "--voltage", "12", "--duration", "0.2", "--csv", csv)
        if name == "fresh":
            monkeypatch.setenv("MECHANISM_TEST_FRESH_CLI", "1")
        result = run_cli(*args)
        assert result.returncode == 0, result.stderr
        outputs.append(csv.read_bytes())
    assert outputs[0] == outputs[1]


def test_a_forked_run_that_dies_by_a_signal_reports_it_as_subprocess_does(tmp_path, monkeypatch):
    """A run killed from outside: minus the signal, as ``subprocess`` gives a killed process."""
    from tests.helpers.cli_server import CliServer

    server = CliServer.get(dict(os.environ), tmp_path)
    if server is None:
        pytest.skip("no fork here: every run takes a fresh interpreter")
    result = server.run(
        ["simulate", "--reduced", "--voltage", "12", "--duration", "600", "--summary"],
        tmp_path,
        dict(os.environ),
        timeout=60,
        after_start=lambda pid: os.kill(pid, signal.SIGKILL),
    )
    assert result.returncode == -signal.SIGKILL
