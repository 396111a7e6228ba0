"""Apply one function to many items, on local worker processes or on a Ray cluster.

``run_batch(function, items, shared=..., setup=...)`` calls ``function(state, item)`` for
every item and returns the results in item order. ``state`` is built once per worker
process by ``setup(shared)`` (default: ``shared`` itself), so a heavy payload (a compiled
model, meshes, their collision trees) travels and is prepared once per worker, never
once per item. Results reach ``on_result(index, result)`` as they complete, so a caller
can write a CSV row by row and resume an interrupted batch later.

- ``backend="local"``: ``workers`` processes (``workers=1``: in this process). The payload
  goes to each worker once through the pool's initializer. Everything handed over is
  pickled, so the pool works with the ``spawn`` start method too (functions must be
  module-level); ``fork`` is used where the platform has it: no re-import of the caller's
  main module, and scripts without a ``__main__`` guard work.
- ``backend="ray"``: with ``ray_address`` (or the ``RAY_ADDRESS`` environment variable)
  connect to a running cluster, with no resource arguments (the cluster owns its
  resources; Ray refuses ``num_cpus`` when connecting); without one, start a private
  local instance with ``workers`` CPUs and stop it afterwards. The payload goes once into
  the object store (``ray.put``); each worker process builds its state from it once and
  keeps it for the next items. Items run in chunks as Ray tasks with ``max_retries``: a
  worker (or node) that dies mid-batch has its chunk run again elsewhere, and the results
  stay complete and in order.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections import deque
from typing import Any, Callable, Literal, Sequence, get_args

from mechanism.errors import UserError

Backend = Literal["local", "ray"]  # where a batch runs: local processes, or Ray
BACKENDS: tuple[Backend, ...] = get_args(Backend)
MAX_WORKERS = 1024
RAY_TASK_RETRIES = 3  # reruns of a chunk whose worker process or node died (local pools too)
RAY_INSTALL_HINT = "pip install 'mechanism[ray]'"


class BatchLost(UserError):
    """The cluster itself was lost mid-batch (its head died, the connection broke): which items
    did not finish, so a caller can name them (and a sweep resume them)."""

    def __init__(self, message: str, unfinished: list[int], cause: str):
        super().__init__(message)
        self.unfinished, self.cause = unfinished, cause


def item_ranges(indices) -> str:
    """``[0, 1, 2, 5, 7, 8]`` as ``'0-2, 5, 7-8'``."""
    indices = sorted(set(indices))
    parts, start = [], None
    for position, index in enumerate(indices):
        if start is None:
            start = index
        if position + 1 == len(indices) or indices[position + 1] != index + 1:
            parts.append(str(start) if start == index else f"{start}-{index}")
            start = None
    return ", ".join(parts)


def check_options(backend: Backend, workers: int) -> None:
    """Raise UserError for an unknown backend or a worker count out of range."""
    if backend not in BACKENDS:
        raise UserError(f"backend {backend!r}: expected one of {', '.join(BACKENDS)}")
    if not 1 <= workers <= MAX_WORKERS:
        raise UserError(f"workers must be between 1 and {MAX_WORKERS}, got {workers}")


def run_batch(
    function: Callable[[Any, Any], Any],
    items: Sequence,
    *,
    shared: Any = None,
    setup: Callable[[Any], Any] | None = None,
    workers: int = 1,
    backend: Backend = "local",
    ray_address: str | None = None,
    on_result: Callable[[int, Any], None] | None = None,
    progress: bool = True,
    desc: str = "items",
    unit: str = "item",
    chunk_size: int | None = None,
    start_method: str | None = None,
) -> list:
    """``[function(state, item) for item in items]`` with ``state = setup(shared)`` built
    once per worker; see the module docstring. Exceptions raised by ``function`` reach the
    caller (a UserError stays a UserError)."""
    from tqdm import tqdm

    check_options(backend, workers)
    ray = _import_ray() if backend == "ray" else None
    items = list(items)
    results: list = [None] * len(items)
    chunks = _chunks(len(items), workers, chunk_size)
    if ray is not None:
        # connected here, before the bar: a connection error line stands alone
        done = _ray_chunks(
            ray,
            function,
            setup,
            shared,
            items,
            chunks,
            workers,
            started := _connect(ray, workers, ray_address),
            private=started and ray_address_from(ray_address) is None,
        )
    elif workers == 1 or len(chunks) <= 1:
        done = _serial_chunks(function, setup, shared, items, chunks)
    else:
        done = _pool_chunks(function, setup, shared, items, chunks, workers, start_method)
    bar = tqdm(
        total=len(items),
        desc=desc,
        unit=unit,
        disable=not progress,
        file=sys.stderr,
        mininterval=0.5,
    )
    try:
        for pairs in done:
            for index, result in pairs:
                results[index] = result
                if on_result is not None:
                    on_result(index, result)
            bar.update(len(pairs))
    finally:
        bar.close()  # ends the bar's line before any error message
        done.close()  # stops the workers (or disconnects from Ray) also on an error
    return results


def _chunks(count: int, workers: int, chunk_size: int | None) -> list[range]:
    # about 8 chunks per worker (load balance) of at most 16 items (progress, lost work)
    size = chunk_size or max(1, min(16, count // (8 * workers)))
    return [range(start, min(start + size, count)) for start in range(0, count, size)]


def _apply(function, state, items, chunk) -> list[tuple[int, Any]]:
    return [(index, function(state, items[index])) for index in chunk]


def _build_state(setup, shared):
    return setup(shared) if setup is not None else shared


# -- local ------------------------------------------------------------------------------------


def _serial_chunks(function, setup, shared, items, chunks):
    state = _build_state(setup, shared)
    for chunk in chunks:
        yield _apply(function, state, items, chunk)


_LOCAL_STATE: Any = None


class _WorkersRefused(Exception):
    """The system refused the worker processes (no semaphores, a process limit)."""


def _init_local_worker(setup, shared, parent_pid: int | None) -> None:
    global _LOCAL_STATE
    from mechanism.files.interrupts import die_with_parent, ignore_in_worker

    ignore_in_worker()  # a Ctrl-C reaches the whole terminal group: the parent stops the workers
    if parent_pid is not None:  # a killed parent cannot: a worker waiting for work would stay
        die_with_parent(parent_pid)
    _LOCAL_STATE = _build_state(setup, shared)


def _local_chunk(function, chunk_items: list[tuple[int, Any]]) -> list[tuple[int, Any]]:
    return [(index, function(_LOCAL_STATE, item)) for index, item in chunk_items]


def _pool_chunks(function, setup, shared, items, chunks, workers, start_method):
    """The chunks on a pool of worker processes. A worker that dies (out of memory, or killed)
    breaks the whole pool: the chunks that had not come back run again on a new one, as Ray
    reruns a dead worker's tasks, at most ``RAY_TASK_RETRIES`` times."""
    todo, restarts = list(chunks), 0
    while todo:
        lost: list = []
        try:
            yield from _one_pool(function, setup, shared, items, todo, workers, start_method, lost)
        except _WorkersRefused as refused:  # before any result: every chunk of todo is still to do
            import warnings

            left = sum(len(chunk) for chunk in todo)
            warnings.warn(
                f"cannot start worker processes ({refused}): the {left} items run in this process",
                stacklevel=2,
            )
            yield from _serial_chunks(function, setup, shared, items, todo)
            return
        if lost and restarts >= RAY_TASK_RETRIES:
            unfinished = sorted(i for chunk in lost for i in chunk)
            raise UserError(
                f"a worker process died {restarts + 1} times mid-batch (out of memory, or killed): "
                f"{len(unfinished)} of {len(items)} items did not finish (items "
                f"{item_ranges(unfinished)}); the others did"
            )
        if lost:
            import warnings

            rerun = sum(len(chunk) for chunk in lost)
            warnings.warn(
                f"a worker process died (out of memory, or killed): the {rerun} items not yet "
                f"done run on new workers",
                stacklevel=2,
            )
        restarts += bool(lost)
        todo = lost


def _one_pool(function, setup, shared, items, chunks, workers, start_method, lost: list):
    """Run ``chunks`` on one pool, yielding each chunk's results; the chunks a dead worker took
    with it (the whole pool breaks) are appended to ``lost``."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    from mechanism.files.interrupts import deferred, stop_pool

    method = start_method or (
        "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    )
    pool, finished_all = None, False
    try:  # an interrupt at any point, also while the workers start, stops them
        try:
            # the pool's queues need POSIX semaphores (a container without /dev/shm refuses
            # them), its workers start with the first task (a process limit refuses the fork)
            pool = ProcessPoolExecutor(
                max_workers=min(workers, len(chunks)),
                mp_context=multiprocessing.get_context(method),
                initializer=_init_local_worker,
                # a forkserver's workers are its children, not the run's: nothing to tie them to
                initargs=(setup, shared, None if method == "forkserver" else os.getpid()),
            )
            # the items of a chunk travel with it; the payload went once, through the initializer
            pending = {
                pool.submit(_local_chunk, function, [(i, items[i]) for i in chunk]): chunk
                for chunk in chunks
            }
        except OSError as refused:
            raise _WorkersRefused(refused.strerror or str(refused)) from None
        waiting = set(pending)
        while waiting:
            # wait() holds every pending future's lock while it looks: an interrupt raised there
            # leaves one held, and the pool's manager thread, and with it the run's shutdown, waits
            # for it for ever (a sweep hung after SIGTERM). So short slices, each with the signal
            # taking effect at its end.
            with deferred():
                finished, waiting = wait(waiting, timeout=0.1, return_when=FIRST_COMPLETED)
            for future in finished:
                try:
                    result = future.result()
                except BrokenProcessPool:
                    lost.append(pending[future])
                    continue
                yield result
        finished_all = not lost
    finally:
        if pool is not None:
            stop_pool(pool, at_once=not finished_all)


# -- Ray --------------------------------------------------------------------------------------


# Ray's switch for its C++ core's failure-signal handler, read once, when Ray is imported
NO_FAILURE_SIGNAL_HANDLER = "RAY_DISABLE_FAILURE_SIGNAL_HANDLER"


def _import_ray():
    """Ray, for a run of the CLI without its C++ core's failure-signal handler: that handler
    also catches SIGTERM, prints a stack and arms a 3 s alarm, which then aborts the run while it
    cleans up (exit 134, not 143: 3 of 12 runs under load, signalled while ``ray.init`` started
    the instance). The instance the run starts inherits the setting (its workers' crashes then
    leave no C++ stack in their logs). A notebook keeps Ray's behaviour."""
    from mechanism.files import interrupts

    if interrupts.installed():
        os.environ.setdefault(NO_FAILURE_SIGNAL_HANDLER, "1")
    try:
        import ray
    except ImportError:
        raise UserError(f"the ray backend needs Ray: {RAY_INSTALL_HINT}") from None
    return ray


def ray_address_from(ray_address: str | None) -> str | None:
    """The cluster to connect to: the argument, else ``RAY_ADDRESS``, else None (start a local one)."""
    return ray_address or os.environ.get("RAY_ADDRESS") or None


def _connect(ray, workers: int, ray_address: str | None) -> bool:
    """Connect (or start a local instance); True when this call did it and must disconnect."""
    import logging

    if ray.is_initialized():  # the caller's own session: use it as it is
        return False
    address = ray_address_from(ray_address)
    # Ray's own warnings (token set-up, resources) would reach the terminal as raw text
    quiet = {"logging_level": logging.ERROR, "log_to_driver": False}
    if address:
        _check_reachable(address)
        try:
            # Ray's C++ core logs every failed attempt to reach the cluster
            with _native_stderr_muted(), _our_signal_handlers_kept(ray):
                ray.init(address=address, **quiet)  # no resource arguments: the cluster has its own
        except (ConnectionError, RuntimeError, ValueError) as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            # Ray sends its token (~/.ray/auth_token, or RAY_AUTH_TOKEN) to an address named
            # explicitly only when told to: say so, since clusters use tokens by default
            hint = (
                ""
                if os.environ.get("RAY_AUTH_MODE")
                else "; a cluster with token authentication also needs RAY_AUTH_MODE=token"
            )
            raise UserError(
                f"cannot connect to the Ray cluster at {address}: {first}{hint}"
            ) from None
    else:
        # "local": a private instance even when a `ray start` cluster runs on this machine
        from mechanism.files.interrupts import installed

        if installed():  # a CLI run: its instance's processes carry its mark (see below)
            os.environ[RAY_RUN_MARK] = f"{os.getpid()}-{os.urandom(6).hex()}"
        try:
            with _our_signal_handlers_kept(ray):
                ray.init(
                    address="local",
                    num_cpus=workers,
                    include_dashboard=False,
                    _temp_dir=ray_temp_dir(),
                    **quiet,
                )
        except (
            BaseException
        ):  # Ctrl-C while it starts: stop what it started (Ray may not know it yet)
            from mechanism.files.interrupts import deferred

            with deferred():
                # at once: Ray's own shutdown of a half-started instance takes seconds
                _stop_private_instance()
                with contextlib.suppress(Exception):
                    ray.shutdown()
            raise
    from mechanism.files.interrupts import reclaim

    reclaim()  # ray.init sets its own SIGTERM handler (sys.exit(15)): a kill must still clean up
    return True


@contextlib.contextmanager
def _our_signal_handlers_kept(ray):
    """While ``ray.init`` starts an instance or connects, a SIGTERM still interrupts the run in
    order: Ray would install handlers that ``sys.exit`` (status 15, or 1 after killing its
    processes) and so bypass the run's cleanup. Only where the CLI's handlers are installed (a
    notebook keeps Ray's behaviour); see also :func:`_import_ray`."""
    from mechanism.files import interrupts

    utils = getattr(getattr(ray, "_private", None), "utils", None)
    original = getattr(utils, "set_sigterm_handler", None)
    if original is None or not interrupts.installed():
        yield
        return
    utils.set_sigterm_handler = lambda handler: None
    try:
        yield
    finally:
        utils.set_sigterm_handler = original


def _descendants(pid: int) -> list[int]:
    """The processes ``pid`` started and theirs (Linux /proc; elsewhere none)."""
    found, todo = [], [pid]
    while todo:
        parent = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{parent}/task")
        except OSError:
            continue
        for task in tasks:
            try:
                with open(f"/proc/{parent}/task/{task}/children") as handle:
                    kids = [int(k) for k in handle.read().split()]
            except (OSError, ValueError):
                continue
            new = [k for k in kids if k not in found]
            found.extend(new)
            todo.extend(new)
    return found


# Every process of a CLI run's private Ray instance inherits this variable, with the run's own
# value: an interrupted run finds them all, also an agent that the raylet started after the run
# last looked at its descendants and that the raylet's death then left to init (under load, a
# DashboardAgent and a RuntimeEnvAgent outlived the run by more than 10 s)
RAY_RUN_MARK = "MECHANISM_RAY_RUN"


def _stop_private_instance() -> None:
    """Kill the run's private Ray instance at once: its descendants, then every process that
    holds the run's mark."""
    _kill(_descendants(os.getpid()))
    mark = os.environ.get(RAY_RUN_MARK)
    if mark:
        _kill(_marked(f"{RAY_RUN_MARK}={mark}".encode()))


def _marked(entry: bytes) -> list[int]:
    """The other processes whose environment holds ``entry`` (Linux /proc; elsewhere none)."""
    found: list[int] = []
    try:
        names = os.listdir("/proc")
    except OSError:
        return found
    for name in names:
        if not name.isdigit() or int(name) == os.getpid():
            continue
        try:
            with open(f"/proc/{name}/environ", "rb") as handle:
                if entry in handle.read().split(b"\0"):
                    found.append(int(name))
        except OSError:
            continue
    return found


def _kill(pids: list[int]) -> None:
    import signal

    for pid in pids:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)


# Ray puts Unix sockets under its temporary folder (session_<date>_<pid>/sockets/plasma_store: about
# 70 characters); a socket path may hold 107. Past this length the folder moves to /tmp.
RAY_TEMP_DIR_MAX_CHARS = 32


def ray_temp_dir() -> str:
    """Ray's temporary folder for a local instance: the system's, or /tmp where that path is too long."""
    import tempfile

    preferred = os.path.join(tempfile.gettempdir(), "ray")
    return preferred if len(preferred) <= RAY_TEMP_DIR_MAX_CHARS else f"/tmp/ray-{os.getuid()}"


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast on a HOST:PORT where nothing listens (Ray would retry for minutes)."""
    import socket

    host, _, port = address.rpartition(":")
    if "://" in address or not host or not port.isdigit():
        return  # "auto", ray://..., or no port: left to Ray
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise UserError(
            f"cannot connect to the Ray cluster at {address}: {exc.strerror or exc} "
            "(start one with `ray start --head`, see the README)"
        ) from None


@contextlib.contextmanager
def _native_stderr_muted():
    """Send file descriptor 2 (where native code writes) to /dev/null for the duration."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as sink:
            os.dup2(sink.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


RAY_WAIT_S = 0.1


def _ray_chunks(
    ray, function, setup, shared, items, chunks, workers: int, started: bool, private: bool
):
    pending: dict = {}
    try:
        shared_ref = ray.put(shared)
        task = ray.remote(max_retries=RAY_TASK_RETRIES, num_cpus=1)(_ray_chunk)
        # a bounded number of chunks in flight: the rest wait here, not in the object store
        limit = 2 * max(1, int(ray.cluster_resources().get("CPU", workers)))
        queue = deque(chunks)
        while queue or pending:
            while queue and len(pending) < limit:
                chunk = queue.popleft()
                # the payload's reference rides in a list so that Ray does not fetch and
                # unpickle it for every chunk: the worker does that once (_ray_state)
                ref = task.remote(function, setup, [shared_ref], [(i, items[i]) for i in chunk])
                pending[ref] = chunk
            try:
                ready: list = []
                while not ready:  # back in Python every 0.1 s: a signal is handled at once
                    # (inside one long wait Ray looks for signals about once a second)
                    ready, _ = ray.wait(list(pending), num_returns=1, timeout=RAY_WAIT_S)
                results = [(ref, _ray_result(ray, ref, pending[ref])) for ref in ready[:1]]
            except (UserError, ray.exceptions.RayTaskError):
                raise
            except (ray.exceptions.RayError, ConnectionError) as exc:  # the cluster itself is gone
                unfinished = sorted(i for chunk in [*pending.values(), *queue] for i in chunk)
                text = str(exc).strip()
                cause = type(exc).__name__ + (f": {text.splitlines()[0]}" if text else "")
                raise BatchLost(
                    f"the Ray cluster was lost mid-batch ({cause}): {len(unfinished)} of {len(items)} items "
                    f"did not finish (items {item_ranges(unfinished)}); the others did",
                    unfinished,
                    cause,
                ) from None
            for ref, result in results:
                pending.pop(ref)
                yield result
    finally:
        from mechanism.files.interrupts import deferred, process_ends_after_cleanup

        with deferred():  # a second Ctrl-C must not leave the instance running
            if private and process_ends_after_cleanup():
                # a private instance of an interrupted run whose process ends after its cleanup
                # (os._exit in cli.main): its processes go at once. Ray's orderly shutdown
                # took 1.2-1.4 s here idle and up to 3 s under load, past the 2 s an interrupt
                # may take; after the kill it waits 5 s for the processes it no longer finds
                _stop_private_instance()
            elif (
                started
            ):  # shutdown stops the instance, or ends our job on a cluster: its workers with it
                ray.shutdown()
            else:  # the caller's own Ray session goes on: free its workers of our tasks
                # not force=True: a forced cancel racing a task's reply aborts the driver inside
                # Ray (task_manager.cc "Check failed: it != submissible_tasks_.end()", exit 1)
                for ref in pending:
                    with contextlib.suppress(Exception):
                        ray.cancel(ref)


def _ray_result(ray, ref, chunk):
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        cause = exc.cause
        if isinstance(cause, UserError):
            raise UserError(str(cause)) from None
        raise cause if isinstance(cause, Exception) else exc
    except (
        ray.exceptions.WorkerCrashedError,
        ray.exceptions.NodeDiedError,
        ray.exceptions.ObjectLostError,
    ) as exc:
        raise UserError(
            f"items {chunk.start}-{chunk.stop - 1}: their worker died {RAY_TASK_RETRIES + 1} times "
            f"({type(exc).__name__})"
        ) from None


_RAY_STATE: dict = {}  # per Ray worker process: payload id -> state built from it


def _ray_state(setup, shared_box):
    (ref,) = shared_box
    key = ref.hex()
    if key not in _RAY_STATE:
        import ray

        _RAY_STATE.clear()  # one batch at a time per worker: drop an earlier payload
        _RAY_STATE[key] = _build_state(setup, ray.get(ref))
    return _RAY_STATE[key]


def _ray_chunk(function, setup, shared_box, chunk_items):
    state = _ray_state(setup, shared_box)
    return [(index, function(state, item)) for index, item in chunk_items]
