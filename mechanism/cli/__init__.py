"""The ``mechanism`` command: a thin shell over the Python API.

Each verb lives in its own module in this package and exposes::

    ORDER = 30                      # position in ``mechanism --help``
    def register(subparsers): ...   # add its parser; set_defaults(handler=run)
    def run(args) -> int: ...       # parse nothing more, call one API function, write files

Verbs are discovered automatically, so adding one is one new file. Heavy imports
(mujoco, trimesh, matplotlib) belong inside ``run`` so that ``--help`` stays fast.

Every failure ends as one ``error: ...`` line on stderr and exit status 2; set
``MECHANISM_DEBUG=1`` to see the traceback instead. Each verb runs as one output transaction
(``mechanism.files.outputs``): its declared outputs are checked before any work
(``set_defaults(inputs=..., outputs=..., output_dirs=..., plots=...)``, see ``_guard``), written
to hidden temporaries and published together only when the verb succeeded; text that
third-party C code prints on stderr is captured and reported as one line.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import warnings

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad arguments as one ``error:`` line (exit 2)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"error: {self.prog}: {message} (see {self.prog} --help)\n")
        raise SystemExit(EXIT_BAD_INPUT)


def _verb_modules():
    package = importlib.import_module(__name__)
    modules = []
    for info in pkgutil.iter_modules(package.__path__):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(module, "register"):
            modules.append(module)
    return sorted(modules, key=lambda m: (getattr(m, "ORDER", 100), m.__name__))


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="mechanism",
        description=(
            "Turn a CAD assembly export into a MuJoCo simulation, inspect it, and correct it "
            "against bench recordings. The default model is the shipped sewing machine "
            "(Husqvarna Viking Sapphire 870, Tegsten 2008)."
        ),
        epilog="Run 'mechanism VERB --help' for the options of each verb.",
    )
    from mechanism import __version__

    parser.add_argument("--version", action="version", version=f"mechanism {__version__}")
    subparsers = parser.add_subparsers(dest="verb", metavar="VERB", parser_class=_Parser)
    for module in _verb_modules():
        module.register(subparsers)
    return parser


def _format_warning(message, category, filename, lineno, line=None):
    # on a line of its own, also when a progress bar holds the current one
    start = "" if getattr(sys.stderr, "at_line_start", True) else "\n"
    return f"{start}warning: {' '.join(str(message).split())}\n"


def debug_enabled() -> bool:
    """``MECHANISM_DEBUG`` is on only for 1, true or yes."""
    return os.environ.get("MECHANISM_DEBUG", "").strip().lower() in {"1", "true", "yes"}


def main(argv: list[str] | None = None) -> int:
    from mechanism.files import interrupts

    interrupts.end_process_after_cleanup(argv is None)
    status = _main_in_order(argv)
    if interrupts.process_ends_after_cleanup() and "ray" in sys.modules:
        # The run has cleaned up and said so. Ray's C++ core can crash in its own teardown after a
        # signal reached it while ray.init ran (a segfault seconds later: 2 of 16 runs under
        # load): the process ends here, without the interpreter's and Ray's teardown.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status


def _main_in_order(argv: list[str] | None) -> int:
    from mechanism.files import interrupts

    interrupts.install()  # Ctrl-C and kill end the run in order; a full ulimit -f is an error line
    try:
        return _main(argv)
    except BaseException as exc:  # before the verb started
        # a signal inside an extension module's import surfaces as ImportError("initialization failed")
        if not (isinstance(exc, KeyboardInterrupt) or interrupts.interrupted()):
            raise
        sys.stderr.write("\nerror: interrupted\n")
        return interrupts.exit_status(exc)
    finally:
        interrupts.finish()  # a late second Ctrl-C is ignored until the process exits
        if argv is not None:  # called in-process (tests, scripts): their handlers back
            interrupts.restore()
        else:
            interrupts.ignore_from_now()


def _main(argv: list[str] | None) -> int:
    warnings.formatwarning = _format_warning
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help(sys.stderr)
        return EXIT_BAD_INPUT
    with warnings.catch_warnings():
        # numpy overflow means an input beyond any physical size (huge coordinates): an error, not noise
        warnings.filterwarnings("error", message="overflow encountered", category=RuntimeWarning)
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """The verb, every failure as one ``error:`` line that starts a line of its own."""
    from mechanism.files import interrupts
    from mechanism.files.capture import LineTracker

    stderr = LineTracker(sys.stderr)
    sys.stderr = stderr
    try:
        check_paths(args)
        status = run_verb(args)
        interrupts.checkpoint()  # an interrupt that a library swallowed still ends the run so
        return status
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 - the one place every failure becomes one line
        # Ctrl-C or SIGTERM (files.interrupts), cleaned up on the way here, or what the signal
        # broke on its way (an import, a library's state)
        interrupted = isinstance(exc, KeyboardInterrupt) or interrupts.interrupted()
        interrupts.finish()
        if debug_enabled() and not interrupted:
            raise
        stderr.end_line()
        if interrupted:
            sys.stderr.write("error: interrupted\n")
            return interrupts.exit_status(exc)
        sys.stderr.write(f"error: {describe(exc)}\n")
        return EXIT_BAD_INPUT
    finally:
        sys.stderr.flush()
        sys.stderr = stderr.stream


def _declared(args: argparse.Namespace, kind: str) -> list[tuple[str, object]]:
    """(option label, path) of what the verb declared: attribute names or functions of args."""
    found = []
    for item in getattr(args, kind, ()) or ():
        values = item(args) if callable(item) else getattr(args, item, None)
        label = getattr(item, "label", None) or (
            f"--{item.replace('_', '-')}" if isinstance(item, str) else "output"
        )
        for value in values if isinstance(values, (list, tuple)) else [values]:
            if value:
                found.append((label, value))
    return found


def check_paths(args: argparse.Namespace) -> None:
    """The verb's declared outputs against its inputs, before any work (files.outputs.check_outputs)."""
    from mechanism.files.outputs import check_outputs

    check_outputs(
        _declared(args, "inputs"),
        _declared(args, "outputs"),
        _declared(args, "output_dirs"),
        _declared(args, "plots"),
    )


def run_verb(args: argparse.Namespace) -> int:
    """The verb as one output transaction, with third-party stderr and stdout captured: their
    text becomes one ``warning:`` line, MuJoCo's instability report an error (nothing published)."""
    from mechanism.errors import UserError
    from mechanism.files.capture import (
        UNSTABLE_MARKERS,
        captured_stderr,
        captured_stdout,
        summarize,
    )
    from mechanism.files.outputs import transaction

    _quiet_mujoco_log()
    with transaction(completes_run=True):
        with captured_stderr() as captured, captured_stdout() as printed:
            status = int(args.handler(args) or 0)
        text = "".join(captured) + "".join(printed)
        if any(marker in text for marker in UNSTABLE_MARKERS):
            raise UserError(
                f"the simulation became unstable ({summarize(text, 200)}); check the parameters "
                "(voltage, inductance, friction, loads) or use a smaller time step"
            )
        if text.strip():
            sys.stderr.write(f"warning: {summarize(text)}\n")
    return status


def _quiet_mujoco_log() -> None:
    """MuJoCo writes its warnings to MUJOCO_LOG.TXT in the current folder too: a stray file."""
    try:
        import mujoco

        config = mujoco.MjLogConfig.get()
        config.logto_file = False
        config.set()
    except (ImportError, AttributeError):  # older MuJoCo: nothing to switch off
        pass


def describe(exc: BaseException) -> str:
    """One line for any failure: user errors as written, others with their type."""
    from mechanism.errors import UserError

    text = " ".join(str(exc).split()) or exc.__class__.__name__
    if isinstance(exc, UserError):  # the converters' ExportError among them
        return text
    if isinstance(exc, FileNotFoundError) and exc.filename:
        return f"no such file: {exc.filename}"
    if isinstance(exc, MemoryError):
        return "out of memory: the request is too large for this machine (reduce the counts or sizes asked for)"
    if isinstance(exc, RuntimeWarning) and "overflow" in text:
        return f"numeric overflow ({text}): an input value is out of any physical range"
    from mechanism.files.outputs import disk_problem

    problem = disk_problem(exc)
    if problem is not None:
        where = getattr(exc, "filename", None)
        return f"cannot write {where}: {problem}" if where else f"cannot write: {problem}"
    if isinstance(exc, OSError):
        return f"{exc.strerror or text}: {exc.filename}" if exc.filename else text
    return f"{exc.__class__.__name__}: {text} (set MECHANISM_DEBUG=1 for the traceback)"


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
