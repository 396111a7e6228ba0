"""Transactional outputs: a run publishes all of its outputs or none, and never loses the old ones.

Everything a run writes goes to a hidden temporary sibling first (``.NAME.PID.XXXX.tmp``).
Inside :func:`transaction` (the CLI runs every verb in one) nothing is published until the
whole run succeeded; then files are renamed into place and folders are swapped in whole
(Linux ``renameat2(RENAME_EXCHANGE)``: the old or the new folder is at the path at every
instant; elsewhere rename-old-away, rename-new-in, with the next run restoring a backup a
kill left behind). On any failure every temporary is removed and nothing is published.
Outside a transaction each ``atomic_*`` publishes itself on success (library use).
"""

from __future__ import annotations

import contextlib
import contextvars
import ctypes
import ctypes.util
import errno
import os
import re
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from mechanism.errors import UserError
from mechanism.files.interrupts import checkpoint, commit, deferred

_active: contextvars.ContextVar["Transaction | None"] = contextvars.ContextVar(
    "mechanism_transaction", default=None
)


def _umask_mode(mode: int = 0o666) -> int:
    """The permission a plain ``open()`` would give: mkstemp's private 0600 is wrong for
    outputs that users share and serve."""
    current = os.umask(0)
    os.umask(current)
    return mode & ~current


# ---------------------------------------------------------------- a full disk

DISK_FULL = {
    errno.ENOSPC: "the disk is full",
    errno.EFBIG: "the file size limit is reached (ulimit -f)",
    errno.EDQUOT: "the disk quota is exceeded",
}


def disk_problem(exc: BaseException) -> str | None:
    """What a failed write says about the disk (full, quota, file size limit), or None when
    it is some other failure. ``shutil.copytree`` gathers its errors as text: read that too."""
    if isinstance(exc, shutil.Error):
        text = str(exc)
        for number, cause in DISK_FULL.items():
            if os.strerror(number) in text:
                return f"{cause} ({os.strerror(number)})"
        return None
    if isinstance(exc, OSError) and exc.errno in DISK_FULL:
        return f"{DISK_FULL[exc.errno]} ({os.strerror(exc.errno)})"
    return None


def _disk_error(path: Path, exc: BaseException) -> UserError | None:
    problem = disk_problem(exc)
    if problem is None:
        return None
    return UserError(
        f"output {path}: cannot write it, {problem}; nothing was published and the previous "
        "output is kept"
    )


# ---------------------------------------------------------------- locks


def lock_wait_s() -> float:
    """How long publishing waits for another run publishing the same output
    (``$MECHANISM_LOCK_WAIT_S``, default 60 s; publishing itself takes milliseconds)."""
    text = os.environ.get("MECHANISM_LOCK_WAIT_S", "").strip()
    try:
        return max(0.0, float(text)) if text else 60.0
    except ValueError:
        raise UserError(
            f"$MECHANISM_LOCK_WAIT_S must be a number of seconds, got {text!r}"
        ) from None


def lock_path(path: str | os.PathLike) -> Path:
    """The lock file of an output: ``.NAME.lock`` beside it, holding the pid of its holder."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


def _lock_holder(lock: Path) -> str:
    with contextlib.suppress(OSError, ValueError):
        text = lock.read_text().strip()
        if text:
            return f" (pid {int(text)})"
    return ""


def _try_lock(lock: Path) -> int | None:
    """A descriptor holding ``lock`` (flock), or None while another process holds it. The
    kernel drops a lock when its holder dies: a lock file that a killed run left is taken over."""
    import fcntl

    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, _umask_mode())
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        except BaseException:
            os.close(fd)
            raise
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:  # not a file its last holder removed after we opened it
            with contextlib.suppress(
                OSError
            ):  # the pid only names the holder: a full disk may refuse it
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
            return fd
        os.close(fd)


def _unlock(lock: Path, fd: int) -> None:
    with contextlib.suppress(OSError):
        os.unlink(lock)  # while still held: a waiter that opened it sees another inode and retries
    os.close(fd)


@contextlib.contextmanager
def output_lock(paths, wait_s: float | None = None, busy: str | None = None):
    """Hold the locks of ``paths`` (taken in one order, so two runs never wait on each other).

    Another live run holding one: wait up to ``wait_s`` (default :func:`lock_wait_s`), then
    UserError (``busy`` formatted with ``path`` and ``holder`` says what, if given)."""
    wait_s = lock_wait_s() if wait_s is None else wait_s
    held: list[tuple[Path, int]] = []
    try:
        for path in sorted({Path(p).absolute() for p in paths}):
            lock = lock_path(path)
            deadline = time.monotonic() + wait_s
            while True:
                try:
                    fd = _try_lock(lock)
                except FileNotFoundError:  # the folder is not there (yet): nothing to guard
                    break
                except OSError as exc:
                    raise _disk_error(path, exc) or UserError(
                        f"output {path}: cannot create its lock {lock.name} ({exc.strerror})"
                    ) from None
                if fd is not None:
                    held.append((lock, fd))
                    break
                if time.monotonic() >= deadline:
                    holder = _lock_holder(lock)
                    if busy:
                        raise UserError(busy.format(path=path, holder=holder))
                    raise UserError(
                        f"output {path}: another run{holder} is writing it and did not finish in "
                        f"{wait_s:g} s; wait for it (or raise MECHANISM_LOCK_WAIT_S)"
                    )
                time.sleep(0.05)
        yield
    finally:
        with deferred():
            for lock, fd in reversed(held):
                _unlock(lock, fd)


def _clean_stale_lock(path: Path) -> None:
    """Remove the lock file a killed run left (nobody holds it)."""
    lock = lock_path(path)
    if not os.path.lexists(lock):
        return
    with contextlib.suppress(OSError):
        fd = _try_lock(lock)
        if fd is not None:
            _unlock(lock, fd)


# ---------------------------------------------------------------- temporaries and leftovers


def _temp_prefix(path: Path) -> str:
    return f".{path.name}.{os.getpid()}."


_LEFTOVER = re.compile(
    r"^\.(?P<name>.+)\.(?P<pid>\d+)\.[A-Za-z0-9_]+\.(?P<kind>tmp|old)(?P<suffix>\.[^.]*)?$"
)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_leftovers(path: str | os.PathLike) -> None:
    """Remove the temporaries a killed run left next to ``path``; if the kill came between
    moving an old folder away and moving the new one in, put the old one back."""
    path = Path(path)
    parent = path.parent
    _clean_stale_lock(path)
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return
    for entry in entries:
        match = _LEFTOVER.match(entry.name)
        if not match or match["name"] != path.name or _alive(int(match["pid"])):
            continue
        leftover = Path(entry.path)
        if match["kind"] == "old" and not os.path.lexists(path):
            with contextlib.suppress(OSError):
                os.rename(leftover, path)
                continue
        _remove(leftover)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError, IsADirectoryError, PermissionError):
            os.unlink(path)


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and missing ancestors; return those created (outermost first)."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        if folder.parent == folder:
            break
        folder = folder.parent
    missing.reverse()
    for created in missing:
        try:
            created.mkdir()
        except FileExistsError:
            pass
        except OSError as exc:
            raise UserError(f"cannot create folder {created}: {exc.strerror}") from None
    return missing


# ---------------------------------------------------------------- atomic folder exchange

_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _renameat2():
    if not hasattr(_renameat2, "fn"):
        fn = None
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
            fn = libc.renameat2
            fn.argtypes = [
                ctypes.c_int,
                ctypes.c_char_p,
                ctypes.c_int,
                ctypes.c_char_p,
                ctypes.c_uint,
            ]
        _renameat2.fn = fn
    return _renameat2.fn


def _exchange(a: Path, b: Path) -> bool:
    """Swap two existing paths in one atomic step; False where the system cannot."""
    fn = _renameat2()
    if fn is None:
        return False
    result = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    return result == 0


def swap_in_folder(new: Path, path: Path) -> None:
    """Put folder ``new`` at ``path``; the old folder (if any) is removed only after."""
    new, path = Path(new), Path(path)
    if not os.path.lexists(path):
        os.rename(new, path)
        return
    if _exchange(new, path):
        _remove(new)  # now the old folder
        return
    backup = Path(tempfile.mkdtemp(prefix=_temp_prefix(path), suffix=".old", dir=path.parent))
    os.rmdir(backup)
    os.rename(path, backup)
    try:
        os.rename(new, path)
    except BaseException:
        os.rename(backup, path)
        raise
    _remove(backup)


# ---------------------------------------------------------------- the transaction


@dataclass
class Transaction:
    """Outputs staged by one run: (temporary, destination, is_folder) in order."""

    staged: list[tuple[Path, Path, bool]] = field(default_factory=list)
    created: list[Path] = field(default_factory=list)
    building: list[Path] = field(default_factory=list)  # folders being filled (atomic_dir's block)
    completes_run: bool = False  # the CLI's run: published, it is complete (interrupts.commit)

    def stage(self, temporary: Path, destination: Path, folder: bool) -> None:
        for i, (old_tmp, old_dst, _) in enumerate(self.staged):
            if old_dst == destination:  # written twice in one run: the last write wins
                _remove(old_tmp)
                del self.staged[i]
                break
        self.staged.append((temporary, destination, folder))

    def publish(self) -> None:
        """Files by rename (with a backup link so a failure rolls back), folders by swap;
        under the outputs' locks, so two runs publishing the same outputs at once leave the
        whole of one; a signal waits until it is done (and then finds a run that
        ``completes_run`` complete: it no longer interrupts)."""
        try:
            checkpoint()  # an interrupt that a library swallowed: nothing is published
            lock = output_lock([destination for _, destination, _ in self.staged])
            lock.__enter__()
        except BaseException:
            self.abort()  # another run holds an output: nothing published, no temporary left
            raise
        try:
            with deferred():
                self._publish()
                if self.completes_run:
                    commit()  # a signal that arrived while it published no longer interrupts
        finally:
            lock.__exit__(None, None, None)

    def _publish(self) -> None:
        done: list[tuple[Path, Path | None]] = []
        current = None
        try:
            for temporary, destination, folder in self.staged:
                current = destination
                if folder:
                    swap_in_folder(temporary, destination)
                    done.append((destination, None))
                    continue
                backup = None
                if destination.is_file():
                    backup = destination.with_name(f"{_temp_prefix(destination)}bak.old")
                    try:
                        os.link(destination, backup)
                    except OSError as exc:
                        if disk_problem(
                            exc
                        ):  # no room even for a link: stop before replacing anything
                            raise
                        # a file system without hard links: published without a way back
                        backup = None
                try:
                    os.replace(temporary, destination)
                except BaseException:
                    if backup is not None:
                        with contextlib.suppress(OSError):
                            os.unlink(backup)
                    raise
                done.append((destination, backup))
        except BaseException as exc:
            for destination, backup in reversed(done):
                if backup is not None:
                    with contextlib.suppress(OSError):
                        os.replace(backup, destination)
            self.abort()
            problem = _disk_error(current, exc) if current is not None else None
            if problem is not None:
                raise problem from None
            raise
        for _, backup in done:
            if backup is not None:
                with contextlib.suppress(OSError):
                    os.unlink(backup)
        self.staged.clear()

    def abort(self) -> None:
        with deferred():
            self._abort()

    def _abort(self) -> None:
        for temporary, _, _ in self.staged:
            _remove(temporary)
        self.staged.clear()
        for folder in reversed(self.created):
            with contextlib.suppress(OSError):
                folder.rmdir()
        self.created.clear()


@contextlib.contextmanager
def transaction(independent: bool = False, completes_run: bool = False):
    """All ``atomic_*`` outputs inside are published together at the end, or none on failure.

    A nested transaction joins the outer one, unless ``independent``: then it publishes at
    its own end (for files the run reads back at once, such as a conversion into a cache).
    ``completes_run`` (the CLI's one transaction per run): once published, the run is
    complete and a signal no longer interrupts it (:func:`files.interrupts.commit`)."""
    current = _active.get()
    if current is not None and not independent:
        yield current
        return
    current = Transaction(completes_run=completes_run)
    token = _active.set(current)
    try:
        yield current
    except BaseException:
        current.abort()
        raise
    else:
        current.publish()
    finally:
        _active.reset(token)


def _in_staged_folder(path) -> bool:
    """True for a path inside a folder the running transaction has yet to publish: writing
    there is already invisible until then, and the run may read it back at once (the demo
    diagnoses the recording it just wrote into its output folder)."""
    current = _active.get()
    if current is None:
        return False
    path = Path(path).absolute()
    return any(
        folder and temporary.absolute() in path.parents for temporary, _, folder in current.staged
    ) or any(building.absolute() in path.parents for building in current.building)


def _prepare(path, current: Transaction) -> Path:
    """Parent folder created (and removed again if the transaction fails), leftovers cleaned."""
    path = Path(path)
    current.created.extend(_make_parents(path.parent))
    clean_leftovers(path)
    return path


@contextlib.contextmanager
def _staged(current: Transaction, path: Path, temporary: Path, folder: bool):
    """Yield; then stage ``temporary`` to become ``path`` when the transaction publishes."""
    try:
        yield
    except BaseException as exc:
        with deferred():
            _remove(temporary)
        problem = _disk_error(path, exc)
        if problem is not None:
            raise problem from None
        raise
    current.stage(temporary, path, folder)


def _temporary_file(path: Path, suffix: str) -> Path:
    """An empty temporary sibling of ``path`` with ordinary permissions."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=suffix, dir=path.parent)
    except OSError as exc:
        raise _disk_error(path, exc) or UserError(
            f"output {path}: cannot write in {path.parent} ({exc.strerror})"
        ) from None
    os.close(fd)
    os.chmod(tmp, _umask_mode())
    return Path(tmp)


def _expect_file(path: Path) -> None:
    if path.is_dir():
        raise UserError(f"output {path}: is a folder, expected a file")


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike, mode: str = "w", **open_kwargs):
    """Open a temporary file next to ``path``; on success it replaces ``path`` (at the end of
    the surrounding transaction, if any)."""
    if "b" not in mode:
        open_kwargs.setdefault("encoding", "utf-8")
        open_kwargs.setdefault("newline", "")
    with _atomic_temporary(path) as tmp:
        with open(tmp, mode, **open_kwargs) as handle:
            yield handle


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path next to ``path`` for writers that want a file name
    (matplotlib, trimesh); on success it replaces ``path``."""
    with _atomic_temporary(path, keep_suffix=True) as tmp:
        yield tmp


@contextlib.contextmanager
def _atomic_temporary(path: str | os.PathLike, keep_suffix: bool = False):
    """A temporary file name next to ``path`` (ending in ``.tmp``, or ``.tmp`` and the
    path's suffix for writers that pick the format from it), staged to replace ``path``
    when the transaction succeeds."""
    with transaction(independent=_in_staged_folder(path)) as current:
        path = _prepare(path, current)
        _expect_file(path)
        tmp = _temporary_file(path, f".tmp{path.suffix}" if keep_suffix else ".tmp")
        with _staged(current, path, tmp, folder=False):
            yield tmp


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike, keep: bool = False):
    """Yield a fresh temporary folder next to ``path``; on success it becomes ``path``.

    With ``keep`` the temporary folder starts as a copy of the existing ``path`` (hard links,
    so it costs no space): files the run does not write are kept. An existing ``path`` is
    replaced only after the new content is complete; a file at ``path`` is an error.
    """
    with transaction(independent=_in_staged_folder(path)) as current:
        path = _prepare(path, current)
        if os.path.lexists(path) and not path.is_dir():
            raise UserError(f"output {path}: exists and is not a folder")
        try:
            tmp = Path(tempfile.mkdtemp(prefix=_temp_prefix(path), suffix=".tmp", dir=path.parent))
        except OSError as exc:
            raise _disk_error(path, exc) or UserError(
                f"output {path}: cannot write in {path.parent} ({exc.strerror})"
            ) from None
        with _staged(current, path, tmp, folder=True):
            if keep and path.is_dir():
                _clone(path, tmp)
            else:
                os.chmod(tmp, _umask_mode(0o777))
            current.building.append(tmp)
            try:
                yield tmp
            finally:
                current.building.remove(tmp)


def _clone(source: Path, target: Path) -> None:
    """``target`` (an empty folder) becomes a copy of ``source``: files hard-linked where the
    file system allows, else copied; symbolic links kept as links."""

    def link_or_copy(src, dst):
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)

    shutil.copytree(source, target, symlinks=True, copy_function=link_or_copy, dirs_exist_ok=True)
    shutil.copymode(source, target)


def _same_or_inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check_not_input(
    output: str | os.PathLike, inputs, what: str = "output", folder: bool = False
) -> None:
    """UserError when ``output`` is one of ``inputs`` or, for a folder replaced as a whole,
    holds one (links resolved)."""
    out = Path(output).resolve()
    for item in inputs:
        if item is None:
            continue
        source = Path(item).resolve()
        if out == source or (folder and out in source.parents):
            raise UserError(
                f"{what} {output}: would overwrite the input {item}; choose another path"
            )


PLOT_SUFFIXES = (".png", ".svg", ".pdf")


def _nearest_existing(path: Path) -> Path:
    while not os.path.lexists(path) and path.parent != path:
        path = path.parent
    return path


def _check_writable(label: str, path: Path) -> None:
    ancestor = _nearest_existing(path.parent if not path.exists() else path.parent)
    if not ancestor.is_dir():
        raise UserError(f"{label} {path}: {ancestor} is a file, not a folder")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise UserError(f"{label} {path}: folder {ancestor} is not writable")


def check_outputs(inputs=(), files=(), folders=(), plots=()) -> None:
    """Check a run's outputs before any work; each argument is a list of (label, path).

    An output file is not an input, not a folder, and its folder is writable; an output
    folder (replaced as a whole) is not a file and holds no input and no other output; no
    two outputs share a path; a plot's file name ends in .png, .svg or .pdf."""
    inputs = [path for _, path in inputs if path]
    seen: dict[Path, str] = {}
    for label, path in [*files, *folders]:
        if not path:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise UserError(
                f"{label} {path}: is also the output of {seen[key]}; choose different paths"
            )
        seen[key] = label
    for label, path in plots:
        if path and Path(path).suffix.lower() not in PLOT_SUFFIXES:
            raise UserError(
                f"{label} {path}: unknown plot format {Path(path).suffix or '(none)'!r}; "
                f"use {', '.join(PLOT_SUFFIXES)}"
            )
    for label, path in files:
        if not path:
            continue
        path = Path(path)
        check_not_input(path, inputs, label)
        if path.is_dir():
            raise UserError(f"{label} {path}: is a folder, expected a file name")
        _check_writable(label, path)
    for label, path in folders:
        if not path:
            continue
        path = Path(path)
        if os.path.lexists(path) and not path.is_dir():
            raise UserError(
                f"{label} {path}: exists and is not a folder (it is replaced as a whole: remove it or "
                "choose another name)"
            )
        check_not_input(path, inputs, label, folder=True)
        inside = [
            other for other, lab in seen.items() if lab != label and path.resolve() in other.parents
        ]
        if inside:
            raise UserError(
                f"{label} {path}: the folder is replaced as a whole, and {seen[inside[0]]} "
                f"{inside[0]} lies inside it"
            )
        _check_writable(label, path)


def publish_files(pairs, folder: str | os.PathLike | None = None, inputs=()) -> None:
    """Publish finished files ``(source, destination)`` as one output.

    When every destination lies in ``folder``, ``folder`` is swapped in whole (its other files
    kept): a kill leaves the old or the new folder. A destination that is one of ``inputs``
    is refused before anything is written. Published at once, also inside a run's transaction."""
    pairs = [(Path(src), Path(dst)) for src, dst in pairs]
    protected = {Path(p).resolve() for p in inputs if p is not None}
    for _, destination in pairs:
        if destination.resolve() in protected:
            raise UserError(
                f"output {destination}: would overwrite an input of this run; choose another folder or name"
            )
    with transaction(independent=True):  # the caller reads these files back at once
        _publish_files(pairs, Path(folder) if folder is not None else None)


def _publish_files(pairs, folder: Path | None) -> None:
    here = Path.cwd().resolve()
    if (
        folder is not None
        and not _same_or_inside(here, folder.resolve())
        and all(_same_or_inside(dst.resolve(), folder.resolve()) for _, dst in pairs)
    ):
        with atomic_dir(folder, keep=True) as new:
            for source, destination in pairs:
                target = new / destination.resolve().relative_to(folder.resolve())
                target.parent.mkdir(parents=True, exist_ok=True)
                if os.path.lexists(target):
                    os.unlink(target)  # a hard link to the old file: never write through it
                shutil.copyfile(source, target)
                os.chmod(target, _umask_mode())
        return
    for source, destination in pairs:
        with atomic_path(destination) as tmp:
            shutil.copyfile(source, tmp)
