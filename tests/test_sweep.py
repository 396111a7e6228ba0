"""Dynamic design sweeps (`mechanism sweep`): each variant's metrics equal a single run of the
same variant built the slow, independent way; the flywheel physics against energy and time
constant arguments; break-away against the thesis; resume after a kill; bad variant files."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import mechanism
from mechanism.dynamics.reduced import ReducedModel
from mechanism.inspection.sweep import SweepOptions, run_sweep, variant_machine
from mechanism.inspection.sweep_journal import journal_path, read_journal, sweep_fingerprint
from mechanism.inspection.sweep_metrics import METRICS, variant_metrics
from mechanism.inspection.variants import VariantSet, parameter, variants_from_document

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def machine():
    return mechanism.load_machine()


def _single(machine, params, values, duration_s=2.0):
    """One variant the independent way: a compiled Machine (flywheel/mass as welded bodies,
    an edited description), simulated alone on the reduced model."""
    built, voltage = variant_machine(machine, params, values)
    reduced = ReducedModel(built)
    return variant_metrics(reduced.simulate(voltage, duration_s), reduced)


def _assert_same(single, row, speed_scale):
    for key in METRICS:
        a, b = single[key], row[key]
        if np.isnan(a) or np.isnan(b):
            assert np.isnan(a) and np.isnan(b), key
            continue
        # ripple is a difference of two speeds: compare it on the speed's scale
        scale = speed_scale if key == "ripple_pp_rad_s" else max(abs(a), 1e-12)
        assert abs(a - b) <= 1e-9 * scale, (key, a, b)
    assert single["note"] == row["note"]


@pytest.mark.slow
@pytest.mark.parametrize("case", ["flywheel", "drive", "counterweight"])
def test_sweep_equals_a_single_run_of_the_variant(machine, case):
    shaft, motor = machine.shaft_joint, machine.motor_joint
    tool_part = machine.description.section("tool")["part"]
    if case == "flywheel":
        params = [parameter("fly", f"inertia:{shaft}_kgm2"), parameter("V", "voltage_V")]
        values = [[0.0, 12.0], [4e-4, 12.0], [2e-3, 4.5]]
    elif case == "drive":
        params = [
            parameter("R", "motor:resistance_ohm"),
            parameter("c", f"friction:{shaft}:coulomb_Nm"),
            parameter("v", f"friction:{motor}:viscous_Nm_s_per_rad"),
            parameter("s", "supply:series_resistance_ohm"),
            parameter("duty", "duty_percent"),
        ]
        values = [[0.3, 0.02, 1e-6, 0.1, 40.0], [-0.2, 0.0, 0.0, 0.0, 80.0]]
    else:
        params = [
            parameter("m", f"mass:{tool_part}_kg"),
            parameter("x", f"part:{tool_part}:x_mm"),
            parameter("L", "layers"),
        ]
        values = [[0.03, -8.0, 0.0], [0.01, 5.0, 2.0]]
    variants = VariantSet(
        params, [f"v{i}" for i in range(len(values))], np.array(values, dtype=float)
    )
    result = run_sweep(machine, variants, progress=False)
    for i, vals in enumerate(values):
        single = _single(machine, params, vals)
        _assert_same(single, result.rows[i], single["mean_speed_rpm"] * 2 * np.pi / 60)
    if (
        case == "counterweight"
    ):  # the offset mass changes the gravity torque: the runs must differ from nominal
        nominal = _single(machine, params, [0.0, 0.0, 0.0])
        assert abs(nominal["ripple_pp_rad_s"] - result.rows[0]["ripple_pp_rad_s"]) > 1e-3


def test_flywheel_physics(machine):
    """A flywheel leaves the mean speed (torque balance) alone, cuts the ripple as 1/J (the
    energy a revolution's torque imbalance moves in and out is fixed: Δω ≈ ΔE/(J ω)) and lengthens
    the start in proportion to J (the mechanical time constant)."""
    own = machine.tables.mean_inertia_kgm2
    multiples = [0.0, 1.0, 2.0, 4.0, 8.0]
    document = {
        "parameters": {"fly": f"inertia:{machine.shaft_joint}_kgm2"},
        "sweep": {"fly": [k * own for k in multiples]},
    }
    rows = mechanism.sweep(machine, document, voltage_V=12.0, duration_s=3.0).table()[1:]
    speeds = [row["mean_speed_rpm"] for row in rows]
    assert max(speeds) - min(speeds) < 5e-4 * speeds[0]
    energy = [row["ripple_pp_rad_s"] * (1 + k) * own for row, k in zip(rows, multiples)]
    assert rows[-1]["ripple_pp_rad_s"] < rows[0]["ripple_pp_rad_s"] / 5
    assert np.ptp(energy[1:]) < 0.05 * np.mean(energy[1:])
    settle = [row["settling_s"] for row in rows]
    assert all(b > a for a, b in zip(settle, settle[1:]))
    assert settle[-1] / settle[-2] == pytest.approx(
        (1 + multiples[-1]) / (1 + multiples[-2]), rel=0.08
    )


def test_breakaway_voltage_matches_the_thesis(machine):
    """The highest break-away torque the thesis measured (at the arm) through the belt and the
    stalled motor's Kt/R is the voltage the machine needs to start from every angle."""
    from mechanism.data.reference import thesis

    ref = thesis()
    row = run_sweep(
        machine,
        VariantSet([parameter("V", "voltage_V")], ["a"], np.array([[12.0]])),
        progress=False,
    ).rows[0]
    motor = machine.motor
    expected = (
        ref["static_friction"]["highest_breakaway_arm_Nm"]
        / machine.motor_ratio
        / motor.torque_constant_Nm_A
        * motor.resistance_ohm
    )
    assert row["breakaway_V"] == pytest.approx(expected, rel=0.03)


def test_workers_give_the_same_rows(machine):
    document = {
        "parameters": {"fly": f"inertia:{machine.shaft_joint}_kgm2", "R": "motor:resistance_ohm"},
        "samples": {
            "count": 12,
            "seed": 4,
            "method": "lhs",
            "tolerances": {
                "fly": {"dist": "uniform", "low": 0, "high": 1e-3},
                "R": {"dist": "normal", "std": 0.05},
            },
        },
    }
    variants = variants_from_document(document)
    one = run_sweep(machine, variants, progress=False).table()
    two = run_sweep(machine, variants, workers=2, progress=False).table()
    assert one == two
    draws = variants.values[1:, 0]  # a Latin hypercube puts one draw in each of 12 strata
    assert sorted(np.floor(draws / 1e-3 * 12).astype(int)) == list(range(12))


def test_interrupted_sweep_resumes_to_the_same_table(machine, tmp_path):
    document = {
        "parameters": {"fly": f"inertia:{machine.shaft_joint}_kgm2"},
        "sweep": {"fly": {"start": 0, "stop": 1e-3, "num": 15}},
    }
    variants = variants_from_document(document)
    options = SweepOptions(duration_s=1.0)
    journal = tmp_path / "s.csv.partial"
    seen = []

    def stop_after_six(index, row):
        seen.append(index)
        if len(seen) == 6:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(
            machine, variants, options, journal=journal, progress=False, on_row=stop_after_six
        )
    with open(journal, "a") as handle:  # a kill mid-write leaves a torn line
        handle.write('{"index": 7, "row": {"mean_sp')
    kept = read_journal(journal, sweep_fingerprint(machine, variants, options))
    assert sorted(kept) == sorted(seen)
    resumed = run_sweep(machine, variants, options, journal=journal, resume=True, progress=False)
    assert resumed.resumed == 6
    fresh = run_sweep(machine, variants, options, progress=False)
    assert resumed.table() == fresh.table()
    with pytest.raises(mechanism.UserError, match="different sweep"):
        run_sweep(
            machine,
            variants,
            SweepOptions(duration_s=1.5),
            journal=journal,
            resume=True,
            progress=False,
        )


@pytest.mark.slow
def test_cli_sweep_killed_and_resumed_writes_the_same_csv(cli, tmp_path):
    variants = tmp_path / "v.json"
    variants.write_text(
        json.dumps(
            {
                "parameters": {"fly": "inertia:arm_shaft_kgm2", "V": "voltage_V"},
                "sweep": {"fly": {"start": 0, "stop": 1e-3, "num": 200}, "V": [6, 9, 12]},
            }
        )
    )
    whole, part = tmp_path / "whole.csv", tmp_path / "part.csv"
    assert (
        cli("sweep", "--variants", str(variants), "--csv", str(whole), "--duration", "3").returncode
        == 0
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    args = [
        sys.executable,
        "-m",
        "mechanism",
        "sweep",
        "--variants",
        str(variants),
        "--csv",
        str(part),
        "--duration",
        "3",
    ]
    proc = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    journal = journal_path(part)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if journal.exists() and journal.read_text().count("\n") > 20:
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.01)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the sweep finished before it could be killed"
    assert not part.exists() and journal.exists()
    resumed = cli(
        "sweep", "--variants", str(variants), "--csv", str(part), "--duration", "3", "--resume"
    )
    assert resumed.returncode == 0 and "kept from the interrupted run" in resumed.stdout
    assert part.read_bytes() == whole.read_bytes()
    assert not journal.exists()


@pytest.mark.parametrize(
    "document,message",
    [
        (
            {"parameters": {"fly": "inertia:arm_shat_kgm2"}, "sweep": {"fly": [0, 1e-4]}},
            "arm_shaft",
        ),
        (
            {"parameters": {"hook_timing_dg": None}, "sweep": {"hook_timing_dg": [0, 10]}},
            "hook_timing_deg",
        ),
        ({"parameters": {"m": "mass:neddle_kg"}, "sweep": {"m": [0, 0.01]}}, "needle"),
        (
            {"parameters": {"fly": "inertia:arm_shaft_kgm2"}, "sweep": {"fly": [-1e-4, 1e-4]}},
            ">= 0",
        ),
        ({"parameters": {"R": "motor:resistanse_ohm"}, "sweep": {"R": [0, 0.1]}}, "resistance_ohm"),
        (
            {
                "parameters": {"R": "motor:resistance_ohm"},
                "samples": {"count": 5, "tolerances": {"R": {"dist": "normal", "std": 0.1}}},
            },
            "seed",
        ),
        (
            {
                "parameters": {
                    "a": "voltage_V",
                    "b": "motor:resistance_ohm",
                    "c": "friction:arm_shaft:coulomb_Nm",
                },
                "sweep": {
                    "a": {"start": 1, "stop": 12, "num": 1000},
                    "b": {"start": 0, "stop": 0.1, "num": 1000},
                    "c": {"start": 0, "stop": 0.01, "num": 1000},
                },
            },
            "1000000001 variants",
        ),
        (
            {
                "parameters": {"a": "voltage_V", "b": "motor:resistance_ohm"},
                "sweep": {
                    "a": {"start": 1, "stop": 12, "num": 400},
                    "b": {"start": 0, "stop": 0.1, "num": 400},
                },
            },
            "--yes",
        ),
        ({"parameters": {"R": "motor:resistance_ohm"}, "sweep": {"R": [0, -5]}}, "resistance_ohm"),
    ],
)
def test_bad_variant_files_are_one_error_line_and_write_nothing(
    cli_here, tmp_path, document, message
):
    path = tmp_path / "v.json"
    path.write_text(json.dumps(document))
    out = tmp_path / "out.csv"
    result = cli_here(
        "sweep", "--variants", str(path), "--csv", str(out), "--plot", str(tmp_path / "p.png")
    )
    line = result.assert_bad_input()
    assert message in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.json"]


@pytest.mark.slow
def test_cli_writes_the_contract_columns_and_a_plot(cli, tmp_path):
    path = tmp_path / "v.csv"
    path.write_text("fly_kgm2,voltage_V\n0,7\n0.001,7\n")
    out, plot = tmp_path / "s.csv", tmp_path / "s.png"
    result = cli(
        "sweep", "--variants", str(path), "--csv", str(out), "--plot", str(plot), "--workers", "2"
    )
    # a CSV header names targets or presets: a bare name is no target
    assert result.returncode == 2
    path.write_text("inertia:arm_shaft_kgm2,voltage_V\n0,7\n0.001,7\n")
    result = cli(
        "sweep", "--variants", str(path), "--csv", str(out), "--plot", str(plot), "--workers", "2"
    )
    assert result.returncode == 0, result.stderr
    table = mechanism.read_table(
        out,
        required=[
            "mean_speed_rpm",
            "ripple_pp_rad_s",
            "settling_s",
            "peak_current_A",
            "rms_current_A",
            "voltage_V",
        ],
    )
    # the nominal row runs at the default voltage
    assert list(table["voltage_V"]) == [
        12.0,
        7.0,
        7.0,
    ]
    assert table["ripple_pp_rad_s"][2] < table["ripple_pp_rad_s"][1]
    assert plot.stat().st_size > 10_000


@pytest.mark.slow
def test_full_model_sweep_equals_single_runs_and_agrees_with_the_reduced_model(machine):
    """--full: each row is exactly a single full-model run of the variant (one batched
    mujoco.rollout is the same as one run at a time), and the full model, with its compliant
    belts and loops, agrees with the reduced 1-DOF equation on speed and ripple."""
    from mechanism.dynamics.simulation import simulate

    shaft = machine.shaft_joint
    params = [parameter("fly", f"inertia:{shaft}_kgm2"), parameter("V", "voltage_V")]
    values = np.array([[0.0, 12.0], [1e-3, 7.0], [4e-4, 9.0]])
    variants = VariantSet(params, ["a", "b", "c"], values)
    full = run_sweep(
        machine, variants, SweepOptions(full=True, bearings=(shaft,)), workers=2, progress=False
    )
    reduced = run_sweep(machine, variants, progress=False)
    for i, vals in enumerate(values):
        built, voltage = variant_machine(machine, params, vals, bearings=(shaft,))
        single = variant_metrics(simulate(voltage, 2.0, machine=built), ReducedModel(built))
        _assert_same(single, full.rows[i], single["mean_speed_rpm"] * 2 * np.pi / 60)
        assert full.rows[i]["mean_speed_rpm"] == pytest.approx(
            reduced.rows[i]["mean_speed_rpm"], rel=2e-3
        )
        assert full.rows[i]["ripple_pp_rad_s"] == pytest.approx(
            reduced.rows[i]["ripple_pp_rad_s"], rel=0.05
        )
        # the shaft's bearings carry at least the weight the shaft hangs on them
        assert full.rows[i][f"bearing_{shaft}_peak_N"] > 1.0
    # a run's default voltage reaches the full model too
    plain = VariantSet([params[0]], ["a"], np.array([[0.0]]))
    at_7V = [
        run_sweep(
            machine, plain, SweepOptions(voltage_V=7.0, full=full_model), progress=False
        ).rows[0]["mean_speed_rpm"]
        for full_model in (True, False)
    ]
    assert (
        at_7V[0] == pytest.approx(at_7V[1], rel=2e-3)
        and at_7V[0] < 0.7 * full.rows[0]["mean_speed_rpm"]
    )


@pytest.mark.slow
def test_a_machine_that_is_not_one_dof_runs_on_the_full_model(tmp_path, machine):
    """With its hook's worm gear taken out the shipped machine has two freedoms (the hook turns
    freely): the reduced 1-DOF equation would still drive the hook through its ratio; the sweep
    says so and runs the full model. The free hook barely loads the drive: the speed stays
    within a per cent of the whole machine's."""
    import re

    from mechanism.machine.models import DEFAULT_DESCRIPTION, DEFAULT_MODEL

    folder = tmp_path / "loose"
    folder.mkdir()
    text = DEFAULT_MODEL.read_text()
    meshdir = re.search(r'meshdir="([^"]+)"', text).group(1)
    text = text.replace(
        f'meshdir="{meshdir}"', f'meshdir="{(DEFAULT_MODEL.parent / meshdir).resolve()}"'
    )
    gear = next(
        line for line in text.splitlines() if "coupling:" in line and 'polycoef="0 0.5' in line
    )
    (folder / DEFAULT_MODEL.name).write_text(text.replace(gear + "\n", ""))
    description = re.sub(
        r"(?m)^model = .*$", f'model = "{DEFAULT_MODEL.name}"', DEFAULT_DESCRIPTION.read_text()
    )
    (folder / DEFAULT_DESCRIPTION.name).write_text(description)
    loose = mechanism.load_machine(folder / DEFAULT_DESCRIPTION.name)
    document = {"parameters": {"V": "voltage_V"}, "sweep": {"V": [12.0]}}
    result = mechanism.sweep(loose, document, duration_s=1.5)
    assert (
        result.degrees_of_freedom == 2 and result.model.startswith("full") and result.options.full
    )
    row = result.table()[1]
    assert np.isnan(row["breakaway_V"]) and not row["note"]
    whole = mechanism.sweep(machine, document, duration_s=1.5).table()[1]
    assert row["mean_speed_rpm"] == pytest.approx(whole["mean_speed_rpm"], rel=0.01)


@pytest.mark.slow
def test_a_coupling_ratio_variant(machine):
    """Another motor pulley: the break-away voltage scales as 1/ratio (the stalled motor's torque
    reaches the shaft times the ratio; the break-away friction is all on the shaft side, the
    motor's own friction being viscous only), and each row is the single run of a Machine whose
    compiled coupling has the new ratio."""
    assert "static_Nm" not in machine.description.friction.get(machine.motor_joint, {})
    coupling = next(
        name[len("coupling:") :]
        for name in (machine.model.equality(i).name for i in range(machine.model.neq))
        if name.startswith("coupling:")
        and machine.model.equality(name).data[1] == pytest.approx(machine.motor_ratio)
    )
    params = [parameter("r", f"ratio:{coupling}")]
    values = np.array([[0.0], [1.0], [-2.0]])
    rows = run_sweep(machine, VariantSet(params, ["a", "b", "c"], values), progress=False).rows
    nominal = machine.motor_ratio
    for row, (offset,) in zip(rows, values):
        assert row["breakaway_V"] == pytest.approx(
            rows[0]["breakaway_V"] * nominal / (nominal + offset), rel=1e-9
        )
    built, voltage = variant_machine(machine, params, values[1])
    assert built.motor_ratio == pytest.approx(nominal + 1.0, rel=1e-9)
    reduced = ReducedModel(built)
    _assert_same(variant_metrics(reduced.simulate(voltage, 2.0), reduced), rows[1], 60.0)
    with pytest.raises(mechanism.UserError, match="keep its sign"):
        run_sweep(machine, VariantSet(params, ["bad"], np.array([[-nominal]])), progress=False)
