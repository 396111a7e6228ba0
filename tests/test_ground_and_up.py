"""Ground and up: ``[machine] ground`` fixes a part to the world (an export that grounds nothing
fixes its heaviest part otherwise); ``init --up`` and the export's gravity vector set the up axis,
and init says which it assumed and why."""

import pytest
import textwrap

import numpy as np

from tests.helpers.exports import Gen1Export


def _ungrounded(folder):
    """A light stand and a heavy block on a hinge between them; the export grounds nothing."""
    doc = Gen1Export()
    stand = doc.body("stand", 4.0, (0, 0, 0), np.diag([100.0, 100.0, 100.0]))
    block = doc.body(
        "block",
        262.0,
        (0, 0, -40),
        np.diag([5e4, 5e4, 5e4]),
        named_frames=[("block_tip", (0, 0, -60))],
    )
    doc.joint("stand--block", stand, block, (0, 0, 0), [("revolute", (0, 1, 0))])
    return doc.write(folder / "loose.xml")


def _moving_bodies(mjcf):
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(mjcf))
    return {model.body(b).name for b in range(1, model.nbody) if model.body_weldid[b] != 0}


def test_ground_fixes_the_named_part_of_an_export_that_grounds_nothing(tmp_path):
    from mechanism.converters import convert

    export = _ungrounded(tmp_path)
    default = convert(export, tmp_path / "default")
    assert _moving_bodies(default.mjcf_path) == {"stand"}  # the heaviest part, the block, is fixed
    chosen = convert(export, tmp_path / "chosen", ground="stand")
    assert _moving_bodies(chosen.mjcf_path) == {"block"}


@pytest.mark.slow
def test_ground_in_a_description_reaches_every_verb(tmp_path, cli):
    _ungrounded(tmp_path)
    description = tmp_path / "pendulum.toml"
    description.write_text(
        textwrap.dedent("""\
        [machine]
        name = "pendulum"
        model = "loose.xml"
        ground = "stand"
        [drive]
        motor_joint = "stand--block"
        shaft_joint = "stand--block"
        zero_site = "block_tip"
        [motor]
        type = "dc"
        resistance_ohm = 2.0
        torque_constant_Nm_per_A = 0.05
        back_emf_V_s_per_rad = 0.05
        [friction."stand--block"]
        viscous_Nm_s_per_rad = 0.001
        [tool]
        site = "block_tip"
        """)
    )
    import mechanism

    machine = mechanism.load_machine(description)
    block = machine.model.body("block").id
    assert machine.model.body_weldid[block] != 0
    result = cli("needle", "--machine", description, "--csv", tmp_path / "n.csv")
    assert result.returncode == 0, result.stderr
    # the tip 60 mm below the hinge turns a whole revolution
    assert "stroke: 120.000 mm" in result.stdout


def test_ground_of_an_mjcf_that_does_not_fix_it_is_an_error(tmp_path, cli_here):
    from mechanism.machine.models import shipped_model

    description = tmp_path / "press.toml"
    description.write_text(
        textwrap.dedent(f"""\
        [machine]
        name = "press"
        model = "{shipped_model("press")}"
        ground = "RAM-1"
        [drive]
        motor_joint = "MOTOR_HOUSING-1--MOTOR_ROTOR-1"
        shaft_joint = "BASE_FRAME-1--CRANKSHAFT-1"
        zero_site = "RAM-1"
        [motor]
        type = "dc"
        resistance_ohm = 2.6
        torque_constant_Nm_per_A = 0.045
        back_emf_V_s_per_rad = 0.045
        """)
    )
    line = cli_here(
        "simulate", "--machine", description, "--voltage", "12", "--duration", "0.1", "--summary"
    ).assert_bad_input()
    assert "ground" in line and "RAM-1" in line


@pytest.mark.slow
def test_init_up_converts_a_y_up_export_and_says_why(tmp_path, cli):
    export = _ungrounded(tmp_path)
    draft = tmp_path / "draft.toml"
    assumed = cli("init", export, "-o", draft)
    assert assumed.returncode == 0, assumed.stderr
    assert "up axis: z; assumed" in assumed.stdout
    given = cli("init", export, "-o", draft, "--up", "y", "--force")
    assert given.returncode == 0, given.stderr
    assert "up axis: y; given by --up" in given.stdout
    assert 'up = "y"' in draft.read_text()
    import mechanism

    machine = mechanism.load_machine(draft)
    assert np.allclose(machine.model.opt.gravity, [0, -9.81, 0])


def test_a_gravity_vector_in_a_gen2_export_sets_up():
    from mechanism.converters.convert import detect_up

    class Carrier:
        gravity = np.array([0.0, -9.80665, 0.0])

    assert detect_up(Carrier())[0] == "y"
    Carrier.gravity = np.array([9.81, 0.0, 0.0])
    assert detect_up(Carrier())[0] == "-x"
    Carrier.gravity = None
    up, why = detect_up(Carrier())
    assert up == "z" and "assumed" in why
