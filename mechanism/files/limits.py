"""Limits on untrusted numbers and sizes, checked before any work or allocation.

Every number a verb takes is finite and in its physical range; every input is read by
counting the bytes actually read (a pipe or ``/dev/zero`` reports size 0); every count
that sizes an allocation is checked from the request. The byte and element limits can be
raised with environment variables (``MECHANISM_MAX_INPUT_MB``, ``MECHANISM_MAX_ELEMENTS``), and
a request larger than the memory the machine has available is refused before it allocates
(:func:`check_memory`; ``MECHANISM_MEMORY_MB`` sets that memory instead). ``MECHANISM_CORES``
bounds the cores one run keeps busy (:func:`usable_cores`).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from mechanism.errors import UserError

DEFAULT_MAX_INPUT_MB = 512
DEFAULT_MAX_ELEMENTS = 200_000_000  # float64 values one request may allocate (1.6 GB)


def _env_limit(name: str, default: float) -> float:
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        raise UserError(f"${name} must be a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise UserError(f"${name} must be a positive number, got {text!r}")
    return value


def usable_cores() -> int:
    """The cores one run may keep busy: ``$MECHANISM_CORES`` where several runs share a machine
    (its share: threads beyond it only contend, 10-12 % more CPU for the same diagnosis with two
    runs of two threads on two cores), else the cores this process may run on."""
    text = os.environ.get("MECHANISM_CORES", "").strip()
    if text:
        try:
            value = int(text)
        except ValueError:
            value = 0
        if value < 1:
            raise UserError(
                f"$MECHANISM_CORES must be a whole number of cores, at least 1, got {text!r}"
            )
        return value
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this system
        return os.cpu_count() or 1


def max_input_bytes() -> int:
    """The most bytes one input file may hold (``$MECHANISM_MAX_INPUT_MB``, default 512 MiB)."""
    return int(_env_limit("MECHANISM_MAX_INPUT_MB", DEFAULT_MAX_INPUT_MB) * 2**20)


def max_elements() -> int:
    """The most numbers one request may allocate (``$MECHANISM_MAX_ELEMENTS``)."""
    return int(_env_limit("MECHANISM_MAX_ELEMENTS", DEFAULT_MAX_ELEMENTS))


def read_bounded(path: str | os.PathLike, what: str, limit: int | None = None) -> bytes:
    """The bytes of ``path``, read in chunks and stopped once past ``limit``: the size a file
    claims is not trusted (pipes, devices and growing files claim anything)."""
    path = Path(path)
    adjustable = limit is None
    limit = max_input_bytes() if limit is None else limit
    if path.is_dir():
        raise UserError(f"{what} {path}: is a folder, expected a file")
    too_big = UserError(
        f"{what} {path}: larger than the input limit of {_size(limit)}"
        + (" (raise it with MECHANISM_MAX_INPUT_MB)" if adjustable else "")
    )
    try:
        with open(path, "rb") as handle:
            return read_stream_bounded(handle, limit, too_big)
    except FileNotFoundError:
        raise UserError(f"{what} {path}: no such file") from None
    except OSError as exc:
        raise UserError(f"{what} {path}: cannot read ({exc.strerror})") from None


def read_stream_bounded(stream, limit: int, too_big: Exception) -> bytes:
    """All of ``stream`` in chunks, raising ``too_big`` once past ``limit`` bytes: what a file or a
    decompressor claims about its size is not trusted."""
    chunks: list[bytes] = []
    total = 0
    while True:
        chunk = stream.read(min(1 << 20, limit + 1 - total))
        if not chunk:
            return b"".join(chunks)
        total += len(chunk)
        if total > limit:
            raise too_big
        chunks.append(chunk)


def check_elements(count: float, what: str) -> None:
    """UserError before allocating ``count`` numbers when that exceeds the limit or the
    memory this machine has available."""
    limit = max_elements()
    if not count <= limit:
        raise UserError(
            f"{what}: {count:.3g} values would need {count * 8 / 2**30:.3g} GiB, more than the limit of "
            f"{limit:.3g} values ({limit * 8 / 2**30:.3g} GiB; raise it with MECHANISM_MAX_ELEMENTS)"
        )
    check_memory(count * 8, what)


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _cgroup_available() -> int | None:
    """What a container's memory limit (cgroup v2) leaves, where one is set."""
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text().strip())
    except (OSError, ValueError):
        return None
    return None if limit == "max" else max(0, int(limit) - used)


def available_memory_bytes() -> int | None:
    """The memory a run may still take: ``$MECHANISM_MEMORY_MB`` if set, else the system's
    available memory (``MemAvailable``, and a container's limit where lower); None if unknown."""
    if os.environ.get("MECHANISM_MEMORY_MB", "").strip():
        return int(_env_limit("MECHANISM_MEMORY_MB", 0) * 2**20)
    known = [value for value in (_meminfo_available(), _cgroup_available()) if value is not None]
    return min(known) if known else None


def _size(count: float) -> str:
    """A size in the unit a person reads it in (GiB, MiB, or bytes below a MiB)."""
    if count >= 2**30:
        return f"{count / 2**30:.3g} GiB"
    return f"{count / 2**20:.3g} MiB" if count >= 2**20 else f"{count:.0f} bytes"


def check_memory(needed_bytes: float, what: str) -> None:
    """UserError before allocating when ``needed_bytes`` exceeds the memory available now."""
    available = available_memory_bytes()
    if available is not None and not needed_bytes <= available:
        raise UserError(
            f"{what}: would need about {_size(needed_bytes)} of memory, more than the {_size(available)} "
            "this machine has available; ask for less (a shorter run, a lower rate, a smaller export) "
            "or run it on a larger machine"
        )


def check_number(
    value,
    what: str,
    low: float | None = None,
    high: float | None = None,
    unit: str = "",
    low_open: bool = False,
) -> float:
    """``value`` as a float when finite and within ``[low, high]`` (``(low, high]`` with
    ``low_open``), else a UserError naming ``what`` and the range."""
    problem = range_problem(value, low, high, unit, low_open)
    if problem:
        raise UserError(f"{what}: {problem}")
    return float(value)


def range_problem(value, low=None, high=None, unit: str = "", low_open: bool = False) -> str | None:
    """None for a finite number in range, else why not (``'31 is outside 0-30 V'``)."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return f"expected a number, got {value!r}"
    if not math.isfinite(number):
        return f"{value} is not a finite number ({describe_range(low, high, unit, low_open)})"
    below = low is not None and (number <= low if low_open else number < low)
    if below or (high is not None and number > high):
        return f"{value:g} is outside {describe_range(low, high, unit, low_open)}"
    return None


def describe_range(low=None, high=None, unit: str = "", low_open: bool = False) -> str:
    unit = f" {unit}" if unit else ""
    if low is not None and high is not None:
        return f"{low:g}-{high:g}{unit}" + (f" (above {low:g})" if low_open else "")
    if low is not None:
        return f"{'above' if low_open else 'at least'} {low:g}{unit}"
    if high is not None:
        return f"at most {high:g}{unit}"
    return "any finite number"


def number(
    low: float | None = None,
    high: float | None = None,
    unit: str = "",
    low_open: bool = False,
    integer: bool = False,
):
    """An argparse ``type`` for a finite number in range: a bad value is one ``error:`` line
    naming the option and the range (exit 2) before any work."""

    def parse(text: str):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            kind = "an integer" if integer else "a number"
            raise argparse.ArgumentTypeError(f"expected {kind}, got {text!r}") from None
        problem = range_problem(value, low, high, unit, low_open)
        if problem:
            raise argparse.ArgumentTypeError(problem)
        return value

    parse.__name__ = "integer" if integer else "number"
    return parse
