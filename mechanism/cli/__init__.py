"""The ``mechanism`` command: a thin shell over the Python API.

Each verb lives in its own module in this package and exposes::

    ORDER = 30                      # position in ``mechanism --help``
    def register(subparsers): ...   # add its parser; set_defaults(handler=run)
    def run(args) -> int: ...       # parse nothing more, call one API function, write files

Verbs are discovered automatically, so adding one is one new file. Heavy imports
(mujoco, trimesh, matplotlib) belong inside ``run`` so that ``--help`` stays fast.

Every failure ends as one ``error: ...`` line on stderr and exit status 2; set
``MECHANISM_DEBUG=1`` to see the traceback instead.
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
    return f"warning: {message}\n"


def main(argv: list[str] | None = None) -> int:
    debug = bool(os.environ.get("MECHANISM_DEBUG"))
    warnings.formatwarning = _format_warning
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help(sys.stderr)
        return EXIT_BAD_INPUT
    try:
        return int(args.handler(args) or 0)
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        return 130
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 - the one place every failure becomes one line
        if debug:
            raise
        sys.stderr.write(f"error: {describe(exc)}\n")
        return EXIT_BAD_INPUT


def describe(exc: BaseException) -> str:
    """One line for any failure: user errors as written, others with their type."""
    from mechanism.errors import UserError

    try:
        from mechanism.converters.errors import ExportError
    except ImportError:  # pragma: no cover - converters is part of the package
        ExportError = UserError
    text = " ".join(str(exc).split()) or exc.__class__.__name__
    if isinstance(exc, (UserError, ExportError)):
        return text
    if isinstance(exc, FileNotFoundError):
        return f"no such file: {exc.filename}"
    if isinstance(exc, OSError):
        return f"{exc.strerror or text}: {exc.filename}" if exc.filename else text
    return f"{exc.__class__.__name__}: {text} (set MECHANISM_DEBUG=1 for the traceback)"


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
