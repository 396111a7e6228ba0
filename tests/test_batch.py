"""The batch runner (mechanism.batch): local processes and a real Ray cluster started with
`ray start`; payload once per worker, ordered and complete results, workers that die."""

import contextlib
import json
import os
import shutil
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from mechanism.batch import run_batch
from mechanism.batch.runner import ray_temp_dir
from mechanism.errors import UserError
from tests.helpers.faults import WORKER_REFUSALS, refuse_worker_processes

ROOT = Path(__file__).resolve().parent.parent

# -- item functions (module level: workers import them by name) -------------------------------

_SETUPS = []  # per process: how often setup ran here


def _setup(payload):
    _SETUPS.append(payload["token"])
    return {"offset": payload["offset"], "pid": os.getpid()}


def _shifted(state, item):
    return {"value": item + state["offset"], "pid": state["pid"], "setups_here": len(_SETUPS)}


def _refuse_seven(state, item):
    if item == 7:
        raise UserError("item 7 is bad")
    return item


def _die_once(marker_dir, item):
    """Kill the whole worker process the first time item 5 is attempted."""
    marker = Path(marker_dir) / f"died_{item}"
    if item == 5 and not marker.exists():
        marker.write_text(str(os.getpid()))
        os._exit(1)
    import ray

    return item * item, ray.get_runtime_context().gcs_address  # which cluster ran it


# -- local ------------------------------------------------------------------------------------


def _die_in_item_5(marker_dir, item, times=1):
    """Kill the whole worker process the first ``times`` times item 5 is attempted."""
    markers = sorted(Path(marker_dir).glob("died_5_*"))
    if item == 5 and len(markers) < times:
        (Path(marker_dir) / f"died_5_{len(markers)}").write_text(str(os.getpid()))
        os._exit(1)
    return item * item


def _always_die_in_item_5(marker_dir, item):
    return _die_in_item_5(marker_dir, item, times=10**6)


def test_the_local_pool_reruns_the_items_of_a_worker_that_died(tmp_path):
    """A worker process that dies (out of memory, killed) breaks the whole pool: what had not
    come back runs again on a new pool, each item's result streamed once."""
    seen = []
    with pytest.warns(
        UserWarning, match="a worker process died .* not yet done run on new workers"
    ):
        results = run_batch(
            _die_in_item_5,
            list(range(12)),
            shared=str(tmp_path),
            workers=2,
            chunk_size=2,
            on_result=lambda i, r: seen.append(i),
            progress=False,
        )
    assert len(list(tmp_path.glob("died_5_*"))) == 1  # a worker process really died
    assert results == [i * i for i in range(12)]
    assert sorted(seen) == list(range(12))


def test_an_interrupt_while_the_workers_start_stops_them(monkeypatch):
    """Ctrl-C between two chunks handed to the pool (its workers just forked): the pool is
    stopped before the interrupt goes on, or its workers would run the whole batch while the
    interpreter waits for them at exit."""
    from concurrent.futures import ProcessPoolExecutor

    pools, submit = [], ProcessPoolExecutor.submit

    def interrupted_second(self, *args, **kwargs):
        pools.append(self)
        future = submit(self, *args, **kwargs)
        if len(pools) == 2:
            raise KeyboardInterrupt
        return future

    monkeypatch.setattr(ProcessPoolExecutor, "submit", interrupted_second)
    with pytest.raises(KeyboardInterrupt):
        run_batch(
            _shifted,
            list(range(40)),
            shared={"offset": 0, "pid": 0},
            workers=2,
            chunk_size=2,
            progress=False,
        )
    processes = list(pools[0]._processes.values()) if pools[0]._processes else []
    assert pools[0]._shutdown_thread and not any(p.is_alive() for p in processes)


SIGNAL_INSIDE_WAIT = textwrap.dedent("""
    import os, signal, sys
    from concurrent.futures import _base
    from mechanism.batch import run_batch
    from mechanism.files import interrupts
    from tests.test_batch import _shifted

    interrupts.install()
    enter, calls = _base._AcquireFutures.__enter__, [0]

    def signalled_midway(self):
        # a SIGTERM arriving after wait() took the first future's lock and before the others
        calls[0] += 1
        futures = list(self.futures)
        futures[0]._condition.acquire()
        if calls[0] == 3:
            os.kill(os.getpid(), signal.SIGTERM)
        for future in futures[1:]:
            future._condition.acquire()

    _base._AcquireFutures.__enter__ = signalled_midway
    try:
        run_batch(_shifted, list(range(400)), shared={"offset": 0, "pid": 0}, workers=2,
                  chunk_size=2, progress=False)
    except interrupts.Interrupted:
        print("interrupted")
""")


@pytest.mark.slow
def test_a_signal_while_the_batch_looks_for_results_ends_it(tmp_path):
    """The signal lands while ``concurrent.futures.wait`` holds some of the futures' locks: the
    run still ends at once (the interrupt waited for the end of that look), where it hung with
    the pool's manager thread waiting for a lock no one would release."""
    run = subprocess.run(
        [sys.executable, "-c", SIGNAL_INSIDE_WAIT],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=Path(__file__).resolve().parent.parent,
    )
    assert run.stdout.strip() == "interrupted", (run.stdout, run.stderr)


@pytest.mark.parametrize("refusal", WORKER_REFUSALS)
def test_a_system_that_refuses_worker_processes_gets_its_items_run_here(monkeypatch, refusal):
    """A warning with the system's reason, and every result."""
    reason = refuse_worker_processes(monkeypatch, refusal)
    seen = []
    with pytest.warns(UserWarning, match=f"cannot start worker processes \\({reason}.*12 items"):
        results = run_batch(
            _shifted,
            list(range(12)),
            shared={"offset": 100, "pid": 0},
            workers=2,
            chunk_size=2,
            on_result=lambda i, r: seen.append(i),
            progress=False,
        )
    expected = [_shifted({"offset": 100, "pid": 0}, i) for i in range(12)]
    assert results == expected and sorted(seen) == list(range(12))


def test_an_item_that_kills_every_worker_ends_the_batch_naming_it(tmp_path):
    from mechanism.batch.runner import RAY_TASK_RETRIES

    with (
        pytest.raises(UserError, match=r"died 4 times mid-batch .* of 12 items did not finish"),
        pytest.warns(UserWarning, match="a worker process died"),
    ):
        run_batch(
            _always_die_in_item_5,
            list(range(12)),
            shared=str(tmp_path),
            workers=2,
            chunk_size=2,
            progress=False,
        )
    assert len(list(tmp_path.glob("died_5_*"))) == RAY_TASK_RETRIES + 1


@pytest.mark.parametrize("start_method", ["spawn", "forkserver", None])
def test_local_pool_orders_results_and_sets_up_once_per_worker(start_method):
    seen = []
    items = list(range(40))
    results = run_batch(
        _shifted,
        items,
        shared={"offset": 1000, "token": "x"},
        setup=_setup,
        workers=2,
        chunk_size=3,
        on_result=lambda i, r: seen.append(i),
        progress=False,
        start_method=start_method,
    )
    assert [r["value"] for r in results] == [i + 1000 for i in items]
    assert sorted(seen) == items  # every result streamed once
    # the payload was prepared once per worker, not per item
    assert all(r["setups_here"] == 1 for r in results)
    assert 1 <= len({r["pid"] for r in results}) <= 2 and os.getpid() not in {
        r["pid"] for r in results
    }


def test_serial_runs_in_this_process():
    _SETUPS.clear()
    results = run_batch(
        _shifted, [1, 2, 3], shared={"offset": 10, "token": "s"}, setup=_setup, progress=False
    )
    assert [r["value"] for r in results] == [11, 12, 13]
    assert _SETUPS == ["s"] and {r["pid"] for r in results} == {os.getpid()}


@pytest.mark.parametrize("workers", [1, 2])
def test_a_user_error_in_an_item_reaches_the_caller_after_the_bar(workers, capsys):
    with pytest.raises(UserError, match="item 7 is bad"):
        run_batch(_refuse_seven, range(20), workers=workers, chunk_size=4)
    err = capsys.readouterr().err
    # the bar's line is ended: an error line printed next stands alone
    assert err == "" or err.endswith("\n")


def test_bad_options_and_missing_ray(monkeypatch, capsys):
    with pytest.raises(UserError, match="backend 'dask'"):
        run_batch(_shifted, [1], backend="dask")
    with pytest.raises(UserError, match="workers must be between"):
        run_batch(_shifted, [1], workers=0)
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails
    with pytest.raises(UserError, match="needs Ray"):
        run_batch(_shifted, [1], backend="ray")
    assert capsys.readouterr().err == ""  # no bar was started


@pytest.mark.slow
def test_ray_missing_on_the_command_line_is_one_error_line(cli, tmp_path):
    """A `ray` package that cannot be imported (first on the path) stands for Ray not installed."""
    (tmp_path / "ray").mkdir()
    (tmp_path / "ray" / "__init__.py").write_text("raise ImportError('no ray here')\n")
    variants = tmp_path / "v.csv"
    variants.write_text("coupling:hook_drive:hook_deg\n1\n")
    model = tmp_path / "m.xml"
    from tests.helpers import mechanisms as M

    model.write_text(M.needle_and_plate().to_xml())
    path = os.pathsep.join([str(tmp_path), str(ROOT), os.environ.get("PYTHONPATH", "")])
    result = cli(
        "clearance",
        "--model",
        model,
        "--driver",
        "arm_shaft",
        "--pairs",
        "needle:hook",
        "--variants",
        variants,
        "--backend",
        "ray",
        "--csv",
        tmp_path / "out.csv",
        env={"PYTHONPATH": path},
    )
    assert "the ray backend needs Ray: pip install 'mechanism[ray]'" in result.assert_bad_input()
    assert result.stderr.startswith("error:")  # no progress-bar fragment before it
    assert not (tmp_path / "out.csv").exists()


# -- Ray: a real cluster on 127.0.0.1 ---------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ray_cli() -> str:
    pytest.importorskip(
        "ray", reason="Ray is not installed (it is in the test extra: pip install -e '.[test]')"
    )
    beside = Path(sys.executable).parent / "ray"
    return (
        str(beside) if beside.exists() else shutil.which("ray") or pytest.skip("no `ray` command")
    )


class RayCluster(str):
    """The cluster's HOST:PORT; ``env``: what a driver needs to reach it (token mode, the token's path)."""

    env: dict


@pytest.fixture(scope="module")
def ray_cluster(tmp_path_factory):
    """`ray start --head` on free ports, with a token (Ray's default since 2.5x; older Rays
    ignore RAY_AUTH_MODE); its workers import mechanism and this test module. The driver
    sends the token to an address only in token mode: RAY_AUTH_MODE=token, as a user would.
    The token is made here and named by RAY_AUTH_TOKEN_PATH (Ray's documented variable): the
    cluster never reads or writes ~/.ray, so the test passes on a machine that never ran Ray.
    Nothing here changes this process's environment (each test sets ``env`` for itself), and
    the cluster keeps its own temporary folder: a local Ray instance that another test starts
    meanwhile shares neither its token mode nor its session files."""
    import secrets
    import tempfile

    token = tmp_path_factory.mktemp("ray-auth") / "auth_token"
    token.write_text(secrets.token_hex(32))
    token.chmod(0o600)
    # short: Ray's socket paths must fit 107 bytes
    temp_dir = tempfile.mkdtemp(prefix="rayc-", dir="/tmp")
    ray_cli = _ray_cli()
    driver_env = {
        "RAY_AUTH_MODE": "token",
        "RAY_AUTH_TOKEN_PATH": str(token),
        "RAY_USAGE_STATS_ENABLED": "0",
    }
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        **driver_env,
    )
    env.pop("RAY_ADDRESS", None)
    port = _free_port()
    ports = {
        flag: _free_port()
        for flag in (
            "--node-manager-port",
            "--object-manager-port",
            "--dashboard-agent-listen-port",
            "--dashboard-agent-grpc-port",
            "--runtime-env-agent-port",
            "--metrics-export-port",
        )
    }
    command = [
        ray_cli,
        "start",
        "--head",
        f"--port={port}",
        "--num-cpus=2",
        f"--temp-dir={temp_dir}",
        "--include-dashboard=false",
        "--disable-usage-stats",
        *(f"{flag}={value}" for flag, value in ports.items()),
    ]
    started = subprocess.run(command, env=env, capture_output=True, text=True, timeout=120)
    try:
        assert started.returncode == 0, started.stderr[-2000:]
        cluster = RayCluster(f"127.0.0.1:{port}")
        cluster.env = driver_env
        yield cluster
    finally:
        _stop_the_processes_of(temp_dir)
        shutil.rmtree(temp_dir, ignore_errors=True)


def _running(pid):
    try:
        # a zombie has ended
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0] != "Z"
    except OSError:
        return False


def _stop_the_processes_of(temp_dir, grace_s=2.0):
    """This cluster's processes (each names its folder) and what they started; not `ray stop`,
    which stops every Ray instance on the machine, another worker's or another user's too."""
    import signal

    from mechanism.batch.runner import _descendants

    def named():
        found = []
        for entry in Path("/proc").iterdir():
            if entry.name.isdigit():
                try:
                    if temp_dir.encode() in (entry / "cmdline").read_bytes():
                        found.append(int(entry.name))
                except OSError:
                    pass
        return found

    roots = named()
    everyone = set(roots).union(*(_descendants(pid) for pid in roots))
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in everyone:
            with contextlib.suppress(OSError):
                os.kill(pid, sig)
        deadline = time.monotonic() + grace_s
        while time.monotonic() < deadline and any(_running(pid) for pid in everyone):
            time.sleep(0.1)


@pytest.fixture
def on_cluster(ray_cluster, monkeypatch):
    """The cluster, with this test's environment set to reach it (undone after the test)."""
    for name, value in ray_cluster.env.items():
        monkeypatch.setenv(name, value)
    return ray_cluster


@pytest.mark.slow
@pytest.mark.xdist_group("ray")  # one Ray test at a time (see conftest)
def test_clearance_variants_on_a_ray_cluster_by_address(cli, on_cluster, tmp_path):
    """The CLI connects to the cluster by address (no num_cpus: Ray would refuse) and the
    rows equal the local run's."""
    from tests.helpers import mechanisms as M

    model = tmp_path / "m.xml"
    model.write_text(M.needle_and_plate().to_xml())
    variants = tmp_path / "v.json"
    variants.write_text(
        json.dumps(
            {"parameters": {"t": "coupling:hook_drive:hook_deg"}, "sweep": {"t": [-30, -2, 0]}}
        )
    )
    common = (
        "clearance",
        "--model",
        model,
        "--driver",
        "arm_shaft",
        "--pairs",
        "needle:hook",
        "--variants",
        variants,
    )
    on_ray = cli(
        *common, "--backend", "ray", "--ray-address", on_cluster, "--csv", tmp_path / "ray.csv"
    )
    assert on_ray.returncode == 0, on_ray.stderr
    assert "warning" not in on_ray.stderr  # nothing of Ray's own logging reaches the user
    local = cli(*common, "--csv", tmp_path / "local.csv")
    assert local.returncode == 0, local.stderr
    assert (tmp_path / "ray.csv").read_text() == (tmp_path / "local.csv").read_text()
    assert "pass" in (tmp_path / "ray.csv").read_text()


@pytest.mark.slow
@pytest.mark.xdist_group("ray")  # one Ray test at a time (see conftest)
def test_a_dynamic_sweep_on_the_ray_cluster_equals_the_local_one(cli, on_cluster, tmp_path):
    """`mechanism sweep` by address: the base machine (description, compiled model, tables)
    travels to the workers once and every row equals the local run's, byte for byte."""
    variants = tmp_path / "v.json"
    variants.write_text(
        json.dumps(
            {
                "parameters": {"fly": "inertia:arm_shaft_kgm2", "R": "motor:resistance_ohm"},
                "sweep": {"fly": [0, 5e-4, 1e-3], "R": [0, 0.2]},
            }
        )
    )
    common = ("sweep", "--variants", variants, "--duration", "1")
    on_ray = cli(
        *common, "--backend", "ray", "--ray-address", on_cluster, "--csv", tmp_path / "ray.csv"
    )
    assert on_ray.returncode == 0, on_ray.stderr
    local = cli(*common, "--csv", tmp_path / "local.csv")
    assert local.returncode == 0, local.stderr
    assert (tmp_path / "ray.csv").read_text() == (tmp_path / "local.csv").read_text()


def _in_a_process_of_its_own(function, *args):
    """Ray reads its token mode when it is imported and keeps a driver's state in the process:
    a driver started here, with the environment set just now, would inherit whichever mode and
    node another test's import or instance left behind. A spawned process starts clean."""
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(1) as pool:
        return pool.apply(function, args)


def _rerun_a_dead_workers_items(shared):
    import ray

    seen = []
    results = run_batch(
        _die_once,
        list(range(12)),
        shared=shared,
        workers=2,
        backend="ray",
        chunk_size=2,
        on_result=lambda i, r: seen.append(i),
        progress=False,
    )
    return results, seen, ray.is_initialized()


@pytest.mark.slow
@pytest.mark.xdist_group("ray")  # one Ray test at a time (see conftest)
def test_ray_reruns_the_items_of_a_worker_that_died(on_cluster, tmp_path, monkeypatch):
    pytest.importorskip("ray")
    # the cluster named by the environment, not the argument
    monkeypatch.setenv("RAY_ADDRESS", on_cluster)
    results, seen, still_connected = _in_a_process_of_its_own(
        _rerun_a_dead_workers_items, str(tmp_path)
    )
    items = list(range(12))
    assert (tmp_path / "died_5").exists()  # a worker process really died mid-batch
    # nothing lost, in item order
    assert [square for square, _ in results] == [i * i for i in items]
    assert {address.rpartition(":")[2] for _, address in results} == {on_cluster.rpartition(":")[2]}
    assert sorted(seen) == items
    assert not still_connected  # disconnected from the cluster it did not start


def _fleet_on_the_cluster(recordings, out, address):
    from mechanism.api import drive_nominal
    from mechanism.sysid.fleet import diagnose_fleet

    result = diagnose_fleet(
        recordings,
        out,
        backend="ray",
        ray_address=address,
        progress=False,
        candidates=["torque_ripple"],
        nominal=drive_nominal(None),
    )
    return result.rows


@pytest.mark.slow
@pytest.mark.xdist_group("ray")  # one Ray test at a time (see conftest)
def test_a_fleet_diagnosed_on_the_ray_cluster_equals_one_diagnosis_here(on_cluster, tmp_path):
    """The options travel once, each recording's path per job; a bad recording is reported."""
    from mechanism.api import drive_nominal
    from mechanism.sysid.diagnosis import diagnose
    from mechanism.sysid.recording import read_recording

    recording = ROOT / "assets" / "recordings" / "torque_ripple_seed3.csv"
    broken = tmp_path / "broken.csv"
    broken.write_text("time,voltage,arm_angle\n0,1,0\n")
    rows = _in_a_process_of_its_own(
        _fleet_on_the_cluster, [recording, broken], tmp_path / "out", str(on_cluster)
    )
    assert [row["status"] for row in rows] == ["ok", "error"] and rows[1]["error"]
    here = diagnose(
        read_recording(recording), candidates=["torque_ripple"], nominal=drive_nominal(None)
    ).to_json()
    assert json.loads((tmp_path / "out" / "torque_ripple_seed3.json").read_text()) == json.loads(
        json.dumps(here)
    )
    assert here["final"]["effects"] == ["torque_ripple"]  # what the virtual bench concealed in it


def test_rays_temporary_folder_stays_short_whatever_the_systems(monkeypatch, tmp_path):
    """Ray's socket paths (about 70 characters below its folder) must fit 107 bytes."""
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", "/tmp")
    assert ray_temp_dir() == "/tmp/ray"
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / ("deep/" * 20)))
    assert ray_temp_dir() == f"/tmp/ray-{os.getuid()}"


def test_the_scheduler_keeps_the_tests_named_ray_together_and_no_others():
    from tests.conftest import _is_ray_test

    together = [
        "tests/test_batch.py::test_ray_backend",
        "tests/test_x.py::test_a_kill_stops_the_ray_instance[2-130]",
        "tests/test_batch.py::test_rays_temporary_folder",
        "tests/test_batch.py::test_bad_options_and_missing_ray",
    ]
    apart = [
        "tests/test_x.py::test_array_shape",
        "tests/test_x.py::test_a_parameter_named[ray]",
        "tests/test_ray_module.py::test_local_pool",
        "tests/test_x.py::test_xray_image",
    ]
    assert all(_is_ray_test(n) for n in together) and not any(_is_ray_test(n) for n in apart)
