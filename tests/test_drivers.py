"""The joint a user turns stays a joint: by default the revolute joints in a bearing on the
frame stay in the kinematic tree and the pins between moving parts close the loops;
``convert --driver`` keeps a named joint; a bare model's verbs turn its guessed shaft."""

import math

import mujoco
import numpy as np
import pytest

from tests.helpers.exports import FourBar
from mechanism.converters import convert
from mechanism.machine.roles import guess_roles


def tree_joints(model) -> set[str]:
    return {model.joint(j).name for j in range(model.njnt)}


def test_ground_pivots_stay_joints_and_the_crank_is_the_guessed_shaft(tmp_path):
    export = FourBar().export(tmp_path)
    report = convert(export, tmp_path / "out")
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert {"ground--crank", "rocker--ground"} <= tree_joints(model)
    assert report.n_loop_closures == 1 and report.degrees_of_freedom == 1
    guess = guess_roles(model)
    # the rocker only rocks; the coupler pins are not on the frame
    assert guess.shaft_joint == "ground--crank"


def test_a_named_driver_stays_a_joint(tmp_path):
    export = FourBar().export(tmp_path)
    model = mujoco.MjModel.from_xml_path(
        str(convert(export, tmp_path / "out", drivers=("crank--coupler",)).mjcf_path)
    )
    assert "crank--coupler" in tree_joints(model)
    from mechanism.converters.errors import ExportError

    with pytest.raises(ExportError, match="close matches: crank--coupler"):
        convert(export, tmp_path / "bad", drivers=("crank-coupler",))


@pytest.mark.slow
def test_a_bare_model_cycles_on_its_guessed_shaft_and_follows_freudenstein(tmp_path, cli):
    bar = FourBar()
    report = convert(bar.export(tmp_path), tmp_path / "out")
    out = tmp_path / "rocker.csv"
    result = cli(
        "probe",
        "--model",
        report.mjcf_path,
        "--part",
        "rocker_end",
        "--quantity",
        "position",
        "--cycle",
        "--resolution",
        "10",
        "--csv",
        out,
    )
    assert result.returncode == 0, result.stderr
    from mechanism.files.tables import read_table

    table = read_table(
        out,
        required=[
            "ground--crank_angle_rad",
            "rocker_end_x_mm",
            "rocker_end_y_mm",
            "rocker_end_z_mm",
        ],
    )
    o2, o4, _, _ = bar.points()
    for crank, x, y, z in zip(
        table["ground--crank_angle_rad"],
        table["rocker_end_x_mm"],
        table["rocker_end_y_mm"],
        table["rocker_end_z_mm"],
    ):
        u, v, _ = bar.plane.T @ (np.array([x, y, z]) - bar.origin_mm)
        expected = bar.rocker_angle(bar.crank_angle0 + crank)
        assert math.remainder(
            math.atan2(v - o4[1], u - o4[0]) - expected, 2 * math.pi
        ) == pytest.approx(0.0, abs=1e-6)
