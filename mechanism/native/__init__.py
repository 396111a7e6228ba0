"""Compiled MuJoCo callbacks (C, loaded with ctypes) for the hot paths.

MuJoCo calls physics callbacks (``mjcb_passive``, ``mjcb_act_dyn``, ...) at every step.
A Python callable there costs a GIL round trip per call, far more than a small model's
whole step; a C function installed through ``ctypes`` costs almost nothing and also runs
inside ``mujoco.rollout`` threads. Each ``<name>.c`` in this folder is compiled once per
source/MuJoCo version into a user cache and reused. Callers must keep a pure-Python
fallback for machines without a C compiler (``load`` returns None there).

MuJoCo callbacks are process-global: a callback must leave models it does not recognise
untouched (check a marker in the model before doing anything).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

from mechanism.files.cache import cache_root  # noqa: F401 - where it always was

_HERE = Path(__file__).resolve().parent
# -ffp-contract=off: no fused multiply-adds (some processors' default), so that the compiled
# code and its numpy fallback round alike. -O3 (no -ffast-math: no reassociation, the same
# numbers to the last bit): the lumped kernel 7-13 % faster than at -O2, measured side by side
# in one process on the diagnosis's fit part (ripple, Stribeck, belt, drift)
FLAGS = ("-O3", "-ffp-contract=off", "-shared", "-fPIC")


def cache_dir() -> Path:
    return cache_root() / "native"


def _compiler() -> str | None:
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return name
    return None


@functools.lru_cache(maxsize=None)
def load(name: str) -> ctypes.CDLL | None:
    """The compiled library for ``mechanism/native/<name>.c``, or None if it cannot be built."""
    import mujoco

    source = _HERE / f"{name}.c"
    package = Path(mujoco.__file__).parent
    include = package / "include"
    libraries = sorted(package.glob("libmujoco.so*")) + sorted(package.glob("libmujoco*.dylib"))
    text = source.read_bytes()
    # Link the very libmujoco the Python bindings loaded (same file, so one instance).
    link = [str(libraries[0]), f"-Wl,-rpath,{package}"] if libraries else []
    recipe = " ".join([mujoco.__version__, str(include), sys.platform, *FLAGS, *link]).encode()
    key = hashlib.sha256(text + recipe).hexdigest()[:16]
    target = cache_dir() / f"lib{name}-{key}.so"
    from mechanism.files.cache import file_problem, install_file

    if target.exists() and (problem := file_problem(target)) is not None:
        warnings.warn(f"cache entry {target}: {problem}; rebuilding it")
        target.unlink(missing_ok=True)
    if not target.exists():
        compiler = _compiler()
        if compiler is None:
            warnings.warn(f"no C compiler found: using the slower Python version of '{name}'")
            return None
        tmp = None
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(
                prefix=f".{target.name}.", suffix=".tmp.so", dir=target.parent
            )
            os.close(fd)
            cmd = [
                compiler,
                *FLAGS,
                f"-I{include}",
                str(source),
                "-o",
                tmp,
                *link,
                "-lm",
            ]
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                first = (proc.stderr.strip().splitlines() or ["unknown error"])[0]
                warnings.warn(
                    f"compiling native '{name}' failed ({first}): using the slower Python version"
                )
                return None
            install_file(Path(tmp), target)
        except OSError as exc:  # a full disk or a read-only cache: the run goes on, slower
            warnings.warn(
                f"cannot keep the compiled '{name}' in the cache {target.parent} "
                f"({exc.strerror or exc}): using the slower Python version"
            )
            return None
        finally:
            if tmp is not None:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(tmp)
    return ctypes.CDLL(str(target))
