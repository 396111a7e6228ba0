"""A Ray cluster whose head dies mid-batch (mechanism.batch.runner.BatchLost): the run ends with
one line naming what did not finish (per item, per variant, per recording); a sweep keeps its
finished rows and ``--resume`` completes it. (A worker killed mid-batch is rerun by Ray:
tests/test_batch.py::test_ray_reruns_the_items_of_a_worker_that_died, on a real cluster.)

The cluster here is a stand-in with Ray's interface that runs each task in this process and
loses its head after a given number of results: killing a real head stops every Ray
instance of the user on the machine."""

from __future__ import annotations

import types

import numpy as np
import pytest

import mechanism
from mechanism.batch import BatchLost, run_batch
from mechanism.batch import runner


class RayError(Exception):
    pass


class RayTaskError(RayError):
    pass


class RaySystemError(RayError):
    pass


def fake_ray(results_before_loss: int):
    """Ray's interface, tasks run here at once; after ``results_before_loss`` results every
    wait fails as a driver's does when the head node is gone."""
    exceptions = types.SimpleNamespace(
        RayError=RayError,
        RayTaskError=RayTaskError,
        WorkerCrashedError=RaySystemError,
        NodeDiedError=RaySystemError,
        ObjectLostError=RaySystemError,
    )
    state = {"served": 0, "built": {}}

    class Ref:
        def __init__(self, value):
            self.value = value

    def remote_task(function, setup, shared_box, chunk_items):
        (ref,) = shared_box
        key = id(ref)
        if key not in state["built"]:
            state["built"][key] = setup(ref.value) if setup is not None else ref.value
        return Ref([(index, function(state["built"][key], item)) for index, item in chunk_items])

    def wait(refs, num_returns=1, timeout=None):
        if state["served"] >= results_before_loss:
            raise RaySystemError(
                "System error: Failed to get the GCS address: the head node died\nmore text"
            )
        state["served"] += 1
        return refs[:1], refs[1:]

    def remote(**options):
        return lambda function: types.SimpleNamespace(remote=remote_task)

    return types.SimpleNamespace(
        exceptions=exceptions,
        is_initialized=lambda: True,
        put=Ref,
        remote=remote,
        wait=wait,
        get=lambda ref: ref.value,
        cancel=lambda ref, force=False: None,
        cluster_resources=lambda: {"CPU": 2},
        shutdown=lambda: None,
    )


def square(state, item):
    return item * item


def test_a_lost_head_names_the_items_that_did_not_finish(monkeypatch):
    monkeypatch.setattr(runner, "_import_ray", lambda: fake_ray(results_before_loss=2))
    seen = []
    with pytest.raises(BatchLost) as lost:
        run_batch(
            square,
            list(range(10)),
            backend="ray",
            chunk_size=2,
            progress=False,
            on_result=lambda i, r: seen.append(i),
        )
    assert sorted(seen) == [0, 1, 2, 3]  # what finished reached the caller
    assert lost.value.unfinished == [4, 5, 6, 7, 8, 9]
    message = str(lost.value)
    assert "items 4-9" in message and "6 of 10" in message and "RaySystemError" in message, message
    assert "\n" not in message


def test_a_sweep_whose_head_died_resumes_to_the_whole_table(monkeypatch, tmp_path, machine):
    from mechanism.inspection.sweep import SweepOptions, run_sweep
    from mechanism.inspection.sweep_journal import journal_path
    from mechanism.inspection.variants import VariantSet, parameter

    values = np.linspace(6, 12, 7)[:, None]
    variants = VariantSet(
        [parameter("V", "voltage_V")], [f"v{i}" for i in range(len(values))], values
    )
    options = SweepOptions(duration_s=0.5)
    journal = journal_path(tmp_path / "sweep.csv")
    monkeypatch.setattr(runner, "_import_ray", lambda: fake_ray(results_before_loss=3))
    with pytest.raises(mechanism.UserError, match="lost mid-sweep") as lost:
        run_sweep(machine, variants, options, backend="ray", journal=journal, progress=False)
    assert "--resume" in str(lost.value) and str(journal) in str(lost.value)
    assert journal.read_text().count("\n") == 1 + 3  # the header and the finished rows
    monkeypatch.setattr(runner, "_import_ray", lambda: fake_ray(results_before_loss=10**6))
    resumed = run_sweep(
        machine, variants, options, backend="ray", journal=journal, resume=True, progress=False
    )
    assert resumed.resumed == 3
    fresh = run_sweep(machine, variants, options, progress=False)
    assert resumed.table() == fresh.table()


@pytest.fixture
def machine(tmp_path, monkeypatch):
    monkeypatch.setenv("MECHANISM_CACHE", str(tmp_path / "cache"))  # not the home folder's
    return mechanism.load_machine()
