"""``mechanism ARGS`` in a process of its own without paying the interpreter's start and the
libraries' imports each time: a server per test process imports them and the CLI once and forks
one child per run.

The child is a separate process, as a user's run is: its own file descriptors 1 and 2 (files the
caller reads), its own exit status (an exception at shutdown, ``os._exit`` and a death by signal
all show), its own signal handlers, installed by the console script's entry
(``mechanism.__main__.run``), which it runs with ``sys.argv`` as a shell would give it; the
modules the verb imports while it runs it imports itself, in its own order. What it skips is
Python's start-up, numpy, scipy, mujoco, trimesh, matplotlib and the CLI's parser, about 0.5 s of
CPU per run; anything those print is recorded once and put in front of every run's output. Runs
that a changed environment could make differ at import (a test's own variables, ``env=``) and the
tests about start-up itself take a fresh interpreter (``tests.conftest.run_cli``).
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

# imported before the first fork: the libraries the verbs use, then the CLI as the console
# script imports it, with its parser (built once: its first build imports each verb's module).
# The modules a verb imports when it runs are left to the run, in the run's own order.
PRELOAD = ("numpy", "scipy.optimize", "scipy.signal", "mujoco", "trimesh", "matplotlib.pyplot")


def _preload() -> None:
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)
    import mechanism.__main__  # noqa: F401 - the console script's entry
    from mechanism.cli import build_parser

    build_parser()


# what differs between a test's run and the server's start without changing an import
IGNORED = ("PYTEST_CURRENT_TEST",)


def _without(env: dict[str, str], names) -> dict[str, str]:
    return {k: v for k, v in env.items() if k not in names}


def serve(answer_fd: int) -> None:
    """The server's loop: one JSON request per line on its stdin, answers on ``answer_fd``."""
    answers = os.fdopen(answer_fd, "w", buffering=1)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        saved = os.dup(1), os.dup(2)
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        try:
            _preload()
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
        out.seek(0)
        err.seek(0)
        at_import = out.read().decode(errors="replace"), err.read().decode(errors="replace")
    answers.write(
        json.dumps({"ready": True, "stdout": at_import[0], "stderr": at_import[1]}) + "\n"
    )
    for line in sys.stdin:
        request = json.loads(line)
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            _child(request, answer_fd)  # never returns
        answers.write(json.dumps({"pid": pid}) + "\n")
        _, status = os.waitpid(pid, 0)
        answers.write(json.dumps({"returncode": _returncode(status)}) + "\n")


def _returncode(status: int) -> int:
    """As ``subprocess`` gives it: the exit status, or minus the signal that ended the process."""
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _child(request: dict, answer_fd: int) -> None:
    status = 1
    try:
        os.close(answer_fd)
        for fd, path in ((0, os.devnull), (1, request["stdout"]), (2, request["stderr"])):
            target = os.open(path, os.O_RDONLY if fd == 0 else os.O_WRONLY | os.O_TRUNC)
            os.dup2(target, fd)
            os.close(target)
        sys.stdin = open(0, closefd=False)  # noqa: SIM115 - the process's own descriptors
        sys.stdout = open(1, "w", closefd=False)  # noqa: SIM115
        sys.stderr = open(2, "w", closefd=False)  # noqa: SIM115
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        sys.argv = ["mechanism", *request["argv"]]
        from mechanism.__main__ import run

        try:
            status = run()
        except SystemExit as exc:  # as the interpreter ends on it
            if exc.code is None or isinstance(exc.code, int):
                status = exc.code or 0
            else:
                print(exc.code, file=sys.stderr)
                status = 1
        except BaseException as exc:  # what an uncaught exception does to a real process
            import traceback

            traceback.print_exc()
            if isinstance(exc, KeyboardInterrupt):  # Python ends by its own SIGINT then
                sys.stderr.flush()
                signal.signal(signal.SIGINT, signal.SIG_DFL)
                os.kill(os.getpid(), signal.SIGINT)
            status = 1
        import atexit
        import threading

        # the interpreter's end: it waits for the threads that are not daemons, then atexit
        threading._shutdown()  # type: ignore[attr-defined]
        atexit._run_exitfuncs()
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(status)


class CliServer:
    """One server per test process, started on first use; ``None`` from :meth:`get` where it
    cannot run (no ``fork``)."""

    _instance: CliServer | None = None
    _failed = False  # the server could not start: every run takes a fresh interpreter

    def __init__(self, env: dict[str, str], cwd: Path):
        self.env = dict(env)
        self._one_at_a_time = threading.Lock()  # one request, then its answers, on the pipes
        read_answers, write_answers = os.pipe()
        self.process = subprocess.Popen(
            [
                sys.executable,
                "-c",
                f"from tests.helpers.cli_server import serve; serve({write_answers})",
            ],
            stdin=subprocess.PIPE,
            pass_fds=(write_answers,),
            env=env,
            cwd=cwd,
            text=True,
        )
        os.close(write_answers)
        self.answers = os.fdopen(read_answers, "r")
        try:
            ready = self._answer(timeout=120)
        except BaseException:
            self.process.kill()
            self.process.wait()
            raise
        self.at_import = ready["stdout"], ready["stderr"]

    @classmethod
    def get(cls, env: dict[str, str], cwd: Path) -> CliServer | None:
        if cls._failed or not hasattr(os, "fork"):
            return None
        if cls._instance is None or cls._instance.process.poll() is not None:
            import atexit

            try:
                cls._instance = CliServer(env, cwd)
            except (OSError, RuntimeError, TimeoutError, ValueError):
                # an import that fails here fails in a fresh interpreter too, where the test sees it
                cls._failed = True
                return None
            atexit.register(cls._instance.close)
        return cls._instance

    def close(self) -> None:
        """The server's input ends: it leaves its loop and exits."""
        if self.process.poll() is None and self.process.stdin is not None:
            self.process.stdin.close()
            self.process.wait(timeout=30)

    def serves(self, env: dict[str, str]) -> bool:
        """Whether a run in ``env`` is the run the server's imports saw (pytest names the
        current test in a variable of its own, which nothing reads at import)."""
        return _without(env, IGNORED) == _without(self.env, IGNORED)

    def _answer(self, timeout: float) -> dict:
        ready, _, _ = select.select([self.answers], [], [], timeout)
        if not ready:
            raise TimeoutError
        line = self.answers.readline()
        if not line:
            raise RuntimeError("the CLI test server ended")
        return json.loads(line)

    def run(
        self,
        args: list[str],
        cwd: Path,
        env: dict[str, str],
        timeout: float,
        after_start: Callable[[int], object] | None = None,
    ) -> subprocess.CompletedProcess:
        with self._one_at_a_time, tempfile.TemporaryDirectory(prefix="cli-run-") as folder:
            out, err = Path(folder, "stdout"), Path(folder, "stderr")
            out.touch()
            err.touch()
            request = {
                "argv": args,
                "cwd": str(cwd),
                "env": env,
                "stdout": str(out),
                "stderr": str(err),
            }
            assert self.process.stdin is not None
            self.process.stdin.write(json.dumps(request) + "\n")
            self.process.stdin.flush()
            pid = self._answer(timeout=60)["pid"]
            if after_start is not None:
                after_start(pid)
            try:
                returncode = self._answer(timeout)["returncode"]
            except TimeoutError:
                os.kill(pid, signal.SIGKILL)
                self._answer(timeout=60)
                raise subprocess.TimeoutExpired(["mechanism", *args], timeout) from None
            stdout = self.at_import[0] + out.read_text(errors="replace")
            stderr = self.at_import[1] + err.read_text(errors="replace")
        return subprocess.CompletedProcess(["mechanism", *args], returncode, stdout, stderr)
