"""One shaft angle: every verb that reports an angle of the described shaft counts it from the
described zero in the described direction. The shipped press re-posed (its crank joint reads
70 deg where the ram is at its top) must give the shipped press's angles in every verb."""

import math
import textwrap

import mujoco
import numpy as np
import pytest

from mechanism.machine.models import shipped_model

CRANK = "BASE_FRAME-1--CRANKSHAFT-1"
MOTOR = "MOTOR_HOUSING-1--MOTOR_ROTOR-1"
OFFSET_DEG = 70.0


def _description(folder, model, name):
    path = folder / f"{name}.toml"
    path.write_text(
        textwrap.dedent(f"""\
        [machine]
        name = "{name}"
        model = "{model}"
        [drive]
        motor_joint = "{MOTOR}"
        shaft_joint = "{CRANK}"
        zero_site = "RAM-1"
        [motor]
        type = "dc"
        resistance_ohm = 2.6
        torque_constant_Nm_per_A = 0.045
        back_emf_V_s_per_rad = 0.045
        [friction."{CRANK}"]
        coulomb_Nm = 0.6
        viscous_Nm_s_per_rad = 0.01
        [tool]
        site = "RAM-1"
        plate = "DIE_PLATE-1"
        """)
    )
    return path


@pytest.fixture(scope="module")
def presses(tmp_path_factory):
    """(shipped, re-posed): the re-posed press's crank coordinate is 70 deg at the export's pose."""
    folder = tmp_path_factory.mktemp("reposed")
    source = shipped_model("press")
    spec = mujoco.MjSpec.from_file(str(source))
    spec.meshdir = str((source.parent / spec.meshdir).resolve())
    spec.joint(CRANK).ref = math.radians(OFFSET_DEG)
    reposed = folder / "reposed.xml"
    reposed.write_text(spec.to_xml())
    return _description(folder, source, "shipped"), _description(folder, reposed, "reposed"), folder


def _rows(path):
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    header = lines[0].split(",")
    return {
        name: np.array([float(line.split(",")[i]) for line in lines[1:]])
        for i, name in enumerate(header)
    }


def _answers(description, folder, cli):
    """Each verb's angle of the ram's lowest point (bottom dead centre) [deg]."""
    name = description.stem
    answers = {}
    needle = cli("needle", "--machine", description, "--csv", folder / f"{name}_needle.csv")
    assert needle.returncode == 0, needle.stderr
    line = next(
        line for line in needle.stdout.splitlines() if line.startswith("bottom dead centre")
    )
    answers["needle"] = float(line.split("shaft angle ")[1].split(" deg")[0])
    top = next(line for line in needle.stdout.splitlines() if line.startswith("top dead centre"))
    answers["needle top"] = float(top.split("shaft angle ")[1].split(" deg")[0])
    probe = cli(
        "probe",
        "--machine",
        description,
        "--part",
        "RAM-1",
        "--quantity",
        "position",
        "--cycle",
        "--resolution",
        "0.25",
        "--csv",
        folder / f"{name}_probe.csv",
    )
    assert probe.returncode == 0, probe.stderr
    rows = _rows(folder / f"{name}_probe.csv")
    z = rows["RAM-1_z_mm"]
    answers["probe"] = math.degrees(rows["shaft_angle_rad"][int(np.argmin(z))])
    answers["probe top"] = math.degrees(rows["shaft_angle_rad"][int(np.argmax(z))])
    clearance = cli(
        "clearance",
        "--machine",
        description,
        "--pairs",
        "RAM-1:DIE_PLATE-1",
        "--csv",
        folder / f"{name}_c.csv",
    )
    assert clearance.returncode == 0, clearance.stderr
    answers["clearance"] = float(clearance.stdout.split(" at ")[1].split(" deg")[0])
    simulate = cli(
        "simulate",
        "--machine",
        description,
        "--voltage",
        "12",
        "--duration",
        "0.01",
        "--csv",
        folder / f"{name}_run.csv",
    )
    assert simulate.returncode == 0, simulate.stderr
    answers["simulate start"] = math.degrees(_rows(folder / f"{name}_run.csv")["arm_angle_rad"][0])
    return answers


@pytest.mark.slow
def test_every_verb_reports_the_described_shaft_angle(presses, cli):
    shipped, reposed, folder = presses
    import mechanism

    machine = mechanism.load_machine(reposed)
    assert math.degrees(machine.frame.zero_rad) == pytest.approx(OFFSET_DEG, abs=1e-3)
    expected = _answers(shipped, folder, cli)
    found = _answers(reposed, folder, cli)
    assert expected["needle"] == pytest.approx(180.0, abs=0.5)  # an offset-free slider-crank
    for verb in ("needle", "probe", "clearance"):
        assert found[verb] == pytest.approx(expected[verb], abs=0.3), (verb, found, expected)
        assert found[verb] == pytest.approx(found["needle"], abs=0.3), (verb, found)
    for key in ("needle top", "probe top"):
        assert min(found[key] % 360, 360 - found[key] % 360) < 0.3, (key, found)
    assert found["simulate start"] == pytest.approx(0.0, abs=0.05)
