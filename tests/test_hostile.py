"""Hostile inputs, one test (at least) per class of issue 17, each through the CLI as a user
runs it: one ``error:`` line and exit 2 (or a correct exit 0), no traceback, no third-party
text, nothing half-written, no previous output lost, no input changed, no temporary left."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import mechanisms as M
from tests.helpers.exports import FourBar

REPO = Path(__file__).resolve().parent.parent


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden temporaries included) with its bytes."""
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def no_temporaries(folder: Path) -> bool:
    return not [p for p in folder.rglob(".*") if ".tmp" in p.name or p.name.endswith(".old")]


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("hostile") / "needle.xml"
    path.write_text(M.needle_and_plate().to_xml())
    return path


@pytest.fixture
def profile(tmp_path):
    path = tmp_path / "profile.csv"
    path.write_text("time_s,voltage_V\n0,6\n0.05,12\n")
    return path


# -- 1. non-finite and impossible numbers ---------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, option",
    [
        (
            ["simulate", "--voltage", "nan", "--reduced", "--duration", "0.1", "--summary"],
            "--voltage",
        ),
        (
            [
                "simulate",
                "--voltage",
                "12",
                "--duration",
                "0.1",
                "--inductance",
                "nan",
                "--summary",
            ],
            "--inductance",
        ),
        (
            ["simulate", "--voltage", "12", "--duration", "0.1", "--cogging", "inf", "--summary"],
            "--cogging",
        ),
        (
            ["simulate", "--voltage", "12", "--duration", "0.1", "--rate", "-5", "--summary"],
            "--rate",
        ),
        (["simulate", "--voltage", "12", "--duration", "nan", "--summary"], "duration"),
        (
            [
                "probe",
                "--part",
                "needle_tip",
                "--quantity",
                "position",
                "--voltage",
                "nan",
                "--duration",
                "0.1",
            ],
            "--voltage",
        ),
        (["view", "--voltage", "inf", "--duration", "0.1"], "--voltage"),
        (["stepper", "--sequence", "thread-cut", "--rate", "1e12"], "--rate"),
        (["zigzag", "--spm", "inf"], "--spm"),
        (["clearance", "--pairs", "needle:hook", "--resolution", "nan"], "--resolution"),
    ],
)
def test_non_finite_and_impossible_numbers_are_refused_naming_the_option(
    cli, tmp_path, args, option
):
    out = tmp_path / "out.csv"
    extra = {
        "simulate": ["--csv", out],
        "probe": ["--csv", out],
        "stepper": ["--csv", out],
        "clearance": ["--csv", out],
        "view": ["--html", tmp_path / "v.html"],
        "zigzag": [],
    }[args[0]]
    line = cli(*args, *extra).assert_bad_input()
    assert option in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_a_description_with_a_non_finite_motor_number_is_refused(cli, tmp_path):
    from mechanism.machine.models import DEFAULT_DESCRIPTION

    text = Path(DEFAULT_DESCRIPTION).read_text()
    model_line = next(line for line in text.splitlines() if line.startswith("model"))
    model = (Path(DEFAULT_DESCRIPTION).parent / re.search(r'"([^"]+)"', model_line)[1]).resolve()
    text = text.replace(model_line, f'model = "{model}"')
    lines = [
        ("resistance_ohm = nan" if line.startswith("resistance_ohm") else line)
        for line in text.splitlines()
    ]
    description = tmp_path / "m.toml"
    description.write_text("\n".join(lines) + "\n")
    line = cli(
        "simulate", "--machine", description, "--voltage", "12", "--duration", "0.1", "--summary"
    ).assert_bad_input()
    assert "resistance" in line


def test_a_rollout_that_blows_up_ends_with_the_time_and_the_likely_cause(tmp_path, monkeypatch):
    import mujoco

    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT here
    from mechanism.dynamics.simulation import _rollout_in_chunks
    from mechanism.errors import UserError

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><option timestep="0.001"/><worldbody><body><joint name="j"/><geom size=".1" mass="1"/></body>'
        '</worldbody><actuator><motor joint="j" gear="1"/></actuator></mujoco>'
    )
    data = mujoco.MjData(model)
    control = np.zeros((50, 1))
    control[20:] = 1e300  # MuJoCo resets the state and goes on: the run must not
    with pytest.raises(UserError, match=r"unstable at t = 0\.02\d* s.*time step"):
        _rollout_in_chunks(model, data, control, progress=False)


# -- 2. outputs never overwrite inputs --------------------------------------------------------------


@pytest.mark.slow
def test_simulate_refuses_to_write_over_its_voltage_profile(cli, profile):
    before = profile.read_bytes()
    line = cli("simulate", "--profile", profile, "--reduced", "--csv", profile).assert_bad_input()
    assert "input" in line and profile.read_bytes() == before


def test_identify_refuses_to_write_its_json_over_the_recording(cli, tmp_path):
    recording = tmp_path / "rec.csv"
    recording.write_text("time,voltage,arm_angle\n0,1,0\n1,1,1\n")
    before = recording.read_bytes()
    assert "input" in cli("identify", recording, "--json", recording).assert_bad_input()
    assert recording.read_bytes() == before


@pytest.mark.slow
def test_convert_refuses_to_write_the_model_over_its_export(cli, tmp_path):
    export = FourBar().export(tmp_path)
    before = snapshot(tmp_path)
    assert "input" in cli("convert", export, "-o", tmp_path).assert_bad_input()
    assert snapshot(tmp_path) == before


@pytest.mark.slow
def test_a_report_folder_that_holds_the_recording_is_refused(cli, tmp_path):
    recording = tmp_path / "rec.csv"
    recording.write_text("time,voltage,arm_angle\n0,1,0\n1,1,1\n")
    assert "input" in cli("identify", recording, "--report", tmp_path).assert_bad_input()
    assert recording.exists()


# -- 3. a failed run never destroys the previous good output ------------------------------------------


@pytest.mark.slow
def test_testbench_keeps_the_previous_recording_when_the_truth_cannot_be_written(cli, tmp_path):
    recording = tmp_path / "r.csv"
    assert cli("testbench", "--effect", "none", "--duration", "3", "-o", recording).returncode == 0
    good = recording.read_bytes()
    (tmp_path / "r.truth.json").unlink()
    (tmp_path / "r.truth.json").mkdir()
    cli(
        "testbench", "--effect", "none", "--duration", "3", "--seed", "1", "-o", recording
    ).assert_bad_input()
    assert recording.read_bytes() == good and no_temporaries(tmp_path)


@pytest.mark.slow
def test_a_folder_output_onto_a_regular_file_is_refused_and_the_file_kept(cli, tmp_path):
    target = tmp_path / "notes"
    target.write_text("my notes")
    assert "not a folder" in cli("demo", "--out", target).assert_bad_input()
    assert target.read_text() == "my notes"


@pytest.mark.slow
def test_convert_keeps_the_previous_conversion_when_the_new_one_cannot_be_published(cli, tmp_path):
    (tmp_path / "export").mkdir()
    export = FourBar().export(tmp_path / "export")
    out = tmp_path / "out"
    assert cli("convert", export, "-o", out, "--name", "other").returncode == 0
    (out / "fourbar.xml").mkdir()  # where the next conversion's model would go
    before = snapshot(out)
    cli("convert", export, "-o", out).assert_bad_input()
    assert snapshot(out) == before and no_temporaries(tmp_path)


# -- 4. a failed run leaves nothing of its own ---------------------------------------------------------


@pytest.mark.slow
def test_an_unknown_plot_format_fails_before_the_csv_is_written(cli, tmp_path):
    line = cli(
        "simulate",
        "--voltage",
        "12",
        "--reduced",
        "--duration",
        "0.1",
        "--csv",
        tmp_path / "a.csv",
        "--plot",
        tmp_path / "a.bmp",
    ).assert_bad_input()
    assert ".bmp" in line and list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_an_unwritable_json_path_leaves_no_csv(cli, tmp_path):
    (tmp_path / "taken.json").mkdir()
    cli(
        "stepper",
        "--sequence",
        "thread-cut",
        "--csv",
        tmp_path / "a.csv",
        "--json",
        tmp_path / "taken.json",
    ).assert_bad_input()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.json"]


# -- 5. a killed run leaves the old or the new output, whole -----------------------------------------

KILL_CLI = textwrap.dedent("""
    import sys
    from tests.helpers.killing import kill_before_rename
    from mechanism.cli import main

    kill_before_rename(int(sys.argv[1]))
    sys.exit(main(sys.argv[2:]))
""")
SUBPROCESS_ENV = {**os.environ, "PYTHONPATH": str(REPO)}


def kill_during_publish(args, folder: Path, old, new, cleanup):
    """Run the verb, killing it before its 1st, 2nd, ... rename; each time the output must be
    the old or the new one, whole (after the next run's cleanup). A killed run cannot remove
    its scratch files: they go to a folder of the test's own (``TMPDIR``), not the machine's."""
    outcomes = set()
    scratch = folder.parent / "scratch"
    scratch.mkdir(exist_ok=True)
    for kill_at in range(10):
        run = subprocess.run(
            [sys.executable, "-c", KILL_CLI, str(kill_at), *map(str, args)],
            capture_output=True,
            text=True,
            env={**SUBPROCESS_ENV, "TMPDIR": str(scratch)},
        )
        for path in cleanup:
            from mechanism.files.outputs import clean_leftovers

            clean_leftovers(path)
        state = snapshot(folder)
        assert state in (old, new), (kill_at, sorted(state))
        outcomes.add((state == new, run.returncode < 0))
        if run.returncode >= 0:
            assert run.returncode == 0, run.stderr
            break
        restore(folder, old)
    assert (False, True) in outcomes and (True, False) in outcomes


def restore(folder: Path, files: dict[str, bytes]) -> None:
    import shutil

    shutil.rmtree(folder)
    for name, data in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)


@pytest.mark.slow
def test_convert_killed_while_publishing_leaves_the_old_or_the_new_conversion(cli, tmp_path):
    first, second = tmp_path / "first", tmp_path / "second"
    first.mkdir(), second.mkdir()
    FourBar().export(first)
    export = FourBar(crank=25.0).export(second)
    out = tmp_path / "out"
    assert cli("convert", first / "fourbar.xml", "-o", out).returncode == 0
    (out / "notes.txt").write_text("mine")
    old = snapshot(out)
    assert cli("convert", export, "-o", tmp_path / "reference").returncode == 0
    new = {**snapshot(tmp_path / "reference"), "notes.txt": b"mine"}
    assert old != new
    kill_during_publish(["convert", export, "-o", out], out, old, new, [out])


@pytest.mark.slow
def test_clearance_killed_while_publishing_leaves_each_output_old_or_new(cli, tmp_path, model_file):
    out = tmp_path / "out"
    out.mkdir()
    args = [
        "clearance",
        "--model",
        model_file,
        "--pairs",
        "needle:hook",
        "--resolution",
        "10",
        "--csv",
        out / "c.csv",
        "--json",
        out / "c.json",
    ]
    old = {"c.csv": b"old csv\n", "c.json": b"{}\n"}
    restore(out, old)
    assert cli(*args).returncode == 0
    new = snapshot(out)
    restore(out, old)
    outcomes = set()
    for kill_at in range(6):
        run = subprocess.run(
            [sys.executable, "-c", KILL_CLI, str(kill_at), *map(str, args)],
            capture_output=True,
            text=True,
            env=SUBPROCESS_ENV,
        )
        from mechanism.files.outputs import clean_leftovers

        for name in old:
            clean_leftovers(out / name)
        state = snapshot(out)
        assert set(state) == set(old) and all(state[n] in (old[n], new[n]) for n in old), kill_at
        outcomes.add(run.returncode < 0)
        if run.returncode >= 0:
            assert snapshot(out) == new
            break
        restore(out, old)
    assert outcomes == {True, False}


# -- 6. limits checked before the memory is spent ---------------------------------------------------


@pytest.mark.slow
def test_a_recording_read_from_a_pipe_stops_at_the_input_limit(cli, tmp_path):
    fifo = tmp_path / "rec.csv"
    os.mkfifo(fifo)
    writer = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"import sys\nwith open({str(fifo)!r}, 'w') as f:\n"
            "    f.write('time,voltage,arm_angle\\n')\n    try:\n"
            "        [f.write('0,1,0\\n' * 100000) for _ in range(10)]\n    except BrokenPipeError: pass",
        ],
        stderr=subprocess.DEVNULL,
    )
    try:
        line = cli(
            "identify", fifo, "--json", tmp_path / "x.json", env={"MECHANISM_MAX_INPUT_MB": "1"}
        ).assert_bad_input()
    finally:
        writer.kill()
        writer.wait()
    assert "input limit of 1 MiB" in line and "MECHANISM_MAX_INPUT_MB" in line


def test_a_billion_variants_are_refused_before_any_is_built(tmp_path):
    variants = tmp_path / "v.json"
    axis = {"start": -1, "stop": 1, "num": 1000}
    variants.write_text(
        json.dumps(
            {
                "parameters": {"a": "body:x:x_mm", "b": "body:y:y_mm", "c": "body:z:z_mm"},
                "sweep": {"a": axis, "b": axis, "c": axis},
            }
        )
    )
    script = (
        "import resource, sys\nresource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))\n"
        "from mechanism.inspection.variants import read_variants\nfrom mechanism.errors import UserError\n"
        f"try:\n    read_variants({str(variants)!r})\nexcept UserError as exc:\n    print(exc)\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    assert "1000000001 variants requested, at most" in run.stdout, run.stderr[-500:]


@pytest.mark.slow
def test_a_long_run_at_a_high_rate_is_refused_before_allocating(cli, tmp_path):
    line = cli(
        "simulate",
        "--voltage",
        "12",
        "--duration",
        "3600",
        "--rate",
        "100000",
        "--csv",
        tmp_path / "a.csv",
    ).assert_bad_input()
    assert "GiB" in line and "MECHANISM_MAX_ELEMENTS" in line


@pytest.mark.parametrize("value", ["two", "0", "-1", "1.5"])
@pytest.mark.slow
def test_a_share_of_cores_that_is_no_whole_number_is_one_line_naming_it(
    cli_here, value, monkeypatch, tmp_path
):
    monkeypatch.setenv("MECHANISM_CORES", value)
    recording = Path(__file__).resolve().parent.parent / "assets/recordings/torque_ripple_seed3.csv"
    line = cli_here("diagnose", recording, "--json", tmp_path / "d.json").assert_bad_input()
    assert "MECHANISM_CORES" in line and repr(value) in line


def test_the_share_of_cores_bounds_the_threads_and_workers(monkeypatch):
    from mechanism.files.limits import usable_cores
    from mechanism.sysid import diagnosis, fleet
    from mechanism.sysid.recording import read_recording

    from tests.helpers.nominal import diagnose

    monkeypatch.setenv("MECHANISM_CORES", "3")
    assert usable_cores() == 3
    assert fleet._fit_workers("local", 2) == 1 and fleet._fit_workers("local", 1) is None

    class FirstRound(Exception):
        pass

    def first_round(jobs, runner):
        raise FirstRound(runner.workers)

    monkeypatch.setattr(diagnosis, "_fit_all", first_round)
    recording = read_recording(
        Path(__file__).resolve().parent.parent / "assets/recordings/torque_ripple_seed3.csv"
    )
    with pytest.raises(FirstRound) as workers:
        diagnose(recording)
    assert workers.value.args == (3,)  # the diagnosis fits on its share
    monkeypatch.setenv("MECHANISM_CORES", "8")
    with pytest.raises(FirstRound) as workers:
        diagnose(recording)
    assert workers.value.args == (4,)  # and on 4 worker processes at most

    monkeypatch.delenv("MECHANISM_CORES")
    affinity = getattr(os, "sched_getaffinity", None)
    assert usable_cores() == (len(affinity(0)) if affinity else os.cpu_count())


# -- 7. nothing stray on stderr -----------------------------------------------------------------------


@pytest.mark.slow
def test_mechanism_debug_zero_is_off(cli, tmp_path):
    result = cli(
        "simulate", "--voltage", "12", "--duration", "-1", "--summary", env={"MECHANISM_DEBUG": "0"}
    )
    result.assert_bad_input()


@pytest.mark.slow
def test_huge_stl_coordinates_are_one_error_line_without_numpy_or_mujoco_text(cli, tmp_path):
    export = FourBar().export(tmp_path)
    stl = tmp_path / "crank.stl"
    data = bytearray(stl.read_bytes())
    for i in range(int.from_bytes(data[80:84], "little")):
        start = 84 + 50 * i + 12
        vertices = np.frombuffer(bytes(data[start : start + 36]), "<f4") * np.float32(1e37)
        data[start : start + 36] = vertices.astype("<f4").tobytes()
    stl.write_bytes(bytes(data))
    result = cli("convert", export, "-o", tmp_path / "out")
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.returncode == 2 and len(lines) == 1 and lines[0].startswith("error:"), (
        result.stderr
    )
    assert not (tmp_path / "out").exists()


def test_text_c_code_prints_on_stderr_is_captured(capfd, tmp_path, monkeypatch):
    import mujoco

    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT here
    from mechanism.files.capture import UNSTABLE_MARKERS, captured_stderr

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint name="j"/><geom size=".1"/></body>'
        '</worldbody><actuator><motor joint="j"/></actuator></mujoco>'
    )
    data = mujoco.MjData(model)
    data.ctrl[0] = np.nan
    with captured_stderr() as captured:
        mujoco.mj_step(model, data)
    assert any(marker in captured[0] for marker in UNSTABLE_MARKERS)
    assert capfd.readouterr().err == ""


def test_an_error_after_a_progress_fragment_starts_its_own_line():
    import io

    from mechanism.files.capture import LineTracker

    stream = io.StringIO()
    tracker = LineTracker(stream)
    tracker.write("variants:  40%|####      | 4/10\r")
    tracker.write("variants:  50%|#####")
    tracker.end_line()
    tracker.write("error: ray is not installed\n")
    assert stream.getvalue().splitlines()[-1] == "error: ray is not installed"


def test_a_warning_after_a_progress_fragment_starts_its_own_line(monkeypatch):
    """The CLI's warning format (what Python's showwarning writes to stderr) starts a line of
    its own after a progress bar's fragment, and no empty line after a whole one."""
    import io

    from mechanism.cli import _format_warning
    from mechanism.files.capture import LineTracker

    stream = io.StringIO()
    tracker = LineTracker(stream)
    monkeypatch.setattr(sys, "stderr", tracker)
    tracker.write("variants:  50%|#####")
    tracker.write(_format_warning("a worker process died", UserWarning, "runner.py", 1))
    tracker.write(_format_warning("again", UserWarning, "runner.py", 1))
    lines = stream.getvalue().splitlines()
    assert lines == ["variants:  50%|#####", "warning: a worker process died", "warning: again"]


def test_text_c_code_prints_on_stdout_becomes_one_warning_line_without_colour_codes(capfd):
    """OpenCASCADE (through cascadio) prints coloured messages on descriptor 1: the verb's own
    output stays on stdout, theirs becomes one plain ``warning:`` line on stderr."""
    import argparse
    import os

    from mechanism.cli import run_verb

    def handler(args):
        os.write(1, b"\x1b[0;33mRWGltf_CafWriter skipped node 'x' without geometry data\x1b[0m\n")
        print("result: 42 mm")

    assert run_verb(argparse.Namespace(handler=handler)) == 0
    captured = capfd.readouterr()
    assert captured.out == "result: 42 mm\n"
    assert captured.err == "warning: RWGltf_CafWriter skipped node 'x' without geometry data\n"
