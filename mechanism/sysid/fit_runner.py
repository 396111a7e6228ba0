"""Where the fits of a diagnosis run: here, or spread over worker processes.

Half of each simulation is Python (the drive arrays, the sensor model), which holds the GIL,
so fits on threads ran only 1.1-1.5x faster on two cores. :class:`FitRunner` forks its workers
once per diagnosis, after the problem is prepared: they inherit it (the recording, its
segments, the caches the baseline fit filled) and receive only what each piece of work needs.
Two ways to spread the work, in each round:

- whole waves of a fit per worker (a screening round: a dozen candidates; the all-free refits
  of the best three, two of them on two workers);
- then the fits left over, fewer than the workers (the third of those refits, the fit that
  converges an accepted model, a swap's refit: long fits of every parameter), one at a time
  here, each finite-difference Jacobian's points spread over the workers (a Jacobian of 24
  points on two workers: 1.6-1.75x faster; spreading the Jacobians of every round instead was
  slower than a fit per worker, on the points' transfers and cold caches).

Either way the numbers are the same as in one process, to the last bit: the same code on the
same arrays, and every fit's result comes back with the parent's own structure object.

Processes only where a worker can be tied to the run's life (Linux: it gets SIGKILL when the
run ends in any way, even by SIGKILL); elsewhere the fits of a round run on threads here.
Workers leave SIGINT and SIGTERM to the run, which stops them
(:func:`mechanism.files.interrupts.stop_pool`); a worker that dies (out of memory, killed) has
the round run again here, and the diagnosis goes on without workers.
"""

from __future__ import annotations

import functools
import os
import sys
import warnings
from typing import Sequence

import numpy as np

from mechanism.sysid.identification import FitResult, Objective, Problem, fit


_PROBLEM: Problem | None = None  # a worker's problem: inherited from the run that forked it


class _NoWorkers(Exception):
    """The system refused the worker processes (a process limit or no memory to fork, no POSIX
    semaphores for the pool's queues)."""


def _init_worker(problem: Problem, parent_pid: int) -> None:
    global _PROBLEM
    from mechanism.files.interrupts import die_with_parent, ignore_in_worker

    ignore_in_worker()
    if not die_with_parent(parent_pid):
        raise RuntimeError("a fit worker cannot be tied to the run's life")
    _PROBLEM = problem


def _fit_one(problem: Problem, structure, starts, kwargs: dict, columns=None) -> FitResult:
    """``starts``: the start values, or a function of the problem that gives them (an
    equation-error regression then runs beside the other fits too)."""
    starts = starts(problem) if callable(starts) else starts
    return fit(problem, structure, starts, **kwargs, columns=columns)


def _fit_in_worker(structure, starts, kwargs: dict) -> FitResult:
    assert _PROBLEM is not None, "a fit worker without its problem"
    result = _fit_one(_PROBLEM, structure, starts, kwargs)
    result.structure = None  # type: ignore[assignment]  # the parent puts its own back
    return result


def _points_in_worker(objective: Objective, points: list) -> list[np.ndarray]:
    assert _PROBLEM is not None, "a fit worker without its problem"
    return [objective(_PROBLEM, x) for x in points]


@functools.lru_cache(maxsize=None)
def jacobians_spread() -> bool:
    """Whether scipy can evaluate a Jacobian's points through a map (``least_squares``'s
    ``workers``, scipy >= 1.16): without it a round of fewer fits than workers runs here."""
    import inspect

    from scipy.optimize import least_squares

    return "workers" in inspect.signature(least_squares).parameters


def processes_available() -> bool:
    """Whether workers can be tied to the run's life here (see the module docstring)."""
    import multiprocessing

    return sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()


class FitRunner:
    """Runs jobs ``(structure, starts, kwargs)`` of one problem on up to ``workers`` processes,
    forked when the first round is spread over them, or here (``workers`` 1). Use it as a context
    manager: the workers end with it (at once where it ends by an error or an interrupt)."""

    def __init__(self, problem: Problem, workers: int):
        self.problem = problem
        self.workers = workers
        self.processes = processes_available()
        self._pool = None

    def __enter__(self) -> "FitRunner":
        return self

    def __exit__(self, kind, error, trace) -> None:
        self._stop(at_once=kind is not None)

    def _stop(self, at_once: bool) -> None:
        from mechanism.files.interrupts import stop_pool

        pool, self._pool = self._pool, None
        if pool is not None:
            stop_pool(pool, at_once=at_once)

    def run(self, jobs: Sequence[tuple]) -> list[FitResult]:
        """The jobs' fits, in the jobs' order: whole waves of a fit per worker, then the rest
        (fewer than the workers) one at a time with their Jacobians spread."""
        if self.workers <= 1 or len(jobs) <= 1 and not self.processes:
            return [_fit_one(self.problem, *job) for job in jobs]
        if not self.processes:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(max_workers=self.workers) as threads:
                return list(threads.map(lambda job: _fit_one(self.problem, *job), jobs))
        from concurrent.futures.process import BrokenProcessPool

        waves = len(jobs) - len(jobs) % self.workers
        try:
            futures = [self._pool_started().submit(_fit_in_worker, *job) for job in jobs[:waves]]
            columns = self._points if jacobians_spread() else None
            rest = [
                _fit_one(self.problem, structure, starts, kwargs, columns=columns)
                for structure, starts, kwargs in jobs[waves:]
            ]
            results = [future.result() for future in futures]
        except (BrokenProcessPool, _NoWorkers) as lost:
            self._stop(at_once=True)
            self.workers = 1
            why = (
                f"cannot start fit worker processes ({lost})"
                if isinstance(lost, _NoWorkers)
                else "a fit worker process died (out of memory, or killed)"
            )
            warnings.warn(f"{why}: the diagnosis goes on in this process", stacklevel=2)
            return self.run(jobs)
        for result, (structure, _, _) in zip(results, jobs):
            result.structure = structure
        return results + rest

    def _points(self, objective: Objective, points: list) -> list[np.ndarray]:
        """``objective`` at ``points``, in order: a share of them on each worker."""
        pool = self._pool_started()
        shares = [points[k :: self.workers] for k in range(self.workers)]
        futures = [pool.submit(_points_in_worker, objective, share) for share in shares if share]
        done = [future.result() for future in futures]
        # back into the points' order: point i is share i % workers, place i // workers
        return [done[i % len(done)][i // len(done)] for i in range(len(points))]

    def _pool_started(self):
        if self._pool is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            try:
                # fork: the workers inherit the prepared problem, nothing of it is pickled (the
                # pool's queues need POSIX semaphores: a container without /dev/shm refuses them)
                self._pool = ProcessPoolExecutor(
                    max_workers=self.workers,
                    mp_context=multiprocessing.get_context("fork"),
                    initializer=_init_worker,
                    initargs=(self.problem, os.getpid()),
                )
                self._pool.submit(int).result()  # the workers start with the first task
            except OSError as refused:
                raise _NoWorkers(refused.strerror or str(refused)) from None
        return self._pool
