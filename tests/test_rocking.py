"""Drives that rock: a four-bar driven at its rocker (it cannot turn a whole revolution), with and
without described limits. Checked against the four-bar's dead points (crank and coupler in line),
and every inspection verb runs over the travel instead of a revolution."""

import math
import textwrap

import numpy as np
import pytest

from tests.helpers.exports import FourBar

ROCKER = "rocker--ground"


def _description(folder, limits=None, extra=""):
    text = textwrap.dedent(f"""\
        [machine]
        name = "rocker"
        model = "fourbar.xml"
        [drive]
        motor_joint = "{ROCKER}"
        shaft_joint = "{ROCKER}"
        zero_site = "rocker_end"
        {extra}
        [motor]
        type = "dc"
        resistance_ohm = 2.0
        torque_constant_Nm_per_A = 0.03
        back_emf_V_s_per_rad = 0.03
        [tool]
        site = "rocker_end"
        plate = "frame"
        """)
    if limits:
        text += f'[limits."{ROCKER}"]\nlower_deg = {limits[0]}\nupper_deg = {limits[1]}\n'
    path = folder / "rocker.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def fourbar(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rocker")
    built = FourBar()
    built.export(folder)
    return built, folder


def _dead_points_deg(fourbar: FourBar) -> list[float]:
    """The rocker's extremes, as its joint coordinate: B at b + a and b - a from the crank pivot."""
    theta0 = fourbar.rocker_angle(fourbar.crank_angle0)
    a, b, c, d = fourbar.crank, fourbar.coupler, fourbar.rocker, fourbar.ground
    out = []
    for reach in (b + a, b - a):
        theta = math.acos((reach * reach - d * d - c * c) / (2 * d * c)) * math.copysign(
            1.0, math.sin(theta0)
        )
        out.append(math.degrees(math.remainder(theta - theta0, 2 * math.pi)))
    return sorted(out)


@pytest.mark.slow
def test_a_rocker_without_limits_is_inspected_where_it_assembles(fourbar):
    import mechanism
    from mechanism.kinematics.travel import END_MARGIN

    built, folder = fourbar
    with pytest.warns(UserWarning, match="cannot turn a whole revolution"):
        machine = mechanism.load_machine(_description(folder))
    travel = machine.travel
    assert not travel.rotates and not machine.rotates
    found = sorted(math.degrees(v) for v in (travel.lower, travel.upper))
    # the joint counts either way about the export's axis: compare the ends as a set of magnitudes
    expected = _dead_points_deg(built)
    if not (found[0] < 0 < found[1]) == (expected[0] < 0 < expected[1]) or abs(
        found[0] + expected[1]
    ) < abs(found[0] - expected[0]):
        expected = sorted(-v for v in expected)
    span = expected[1] - expected[0]
    assert found[0] == pytest.approx(expected[0] + END_MARGIN * span, abs=0.05)
    assert found[1] == pytest.approx(expected[1] - END_MARGIN * span, abs=0.05)


@pytest.mark.slow
def test_limits_set_the_travel_the_stops_and_every_verb_runs_over_it(fourbar, cli, tmp_path):
    import mechanism

    _, folder = fourbar
    path = _description(folder, limits=(-40.0, 5.0))
    machine = mechanism.load_machine(path)
    assert (
        math.degrees(machine.travel.lower),
        math.degrees(machine.travel.upper),
    ) == pytest.approx((-40.0, 5.0))
    joint = machine.model.joint(ROCKER).id
    assert machine.model.jnt_limited[joint]
    assert np.degrees(machine.model.jnt_range[joint]) == pytest.approx([-40.0, 5.0])
    # the stop's time constant is the least MuJoCo takes (not its default 20 ms) and it holds the stall torque
    assert machine.model.jnt_solref[joint][0] == pytest.approx(2 * machine.timestep_s)
    assert 0 < machine.stops[ROCKER] <= math.radians(0.5)
    low, high = machine.shaft_span_rad
    assert math.degrees(high - low) == pytest.approx(45.0)
    assert not machine.tables.periodic and machine.tables.angle_rad[0] == pytest.approx(low)

    needle = cli("needle", "--machine", path, "--csv", tmp_path / "n.csv")
    assert needle.returncode == 0, needle.stderr
    assert "rocks between" in needle.stdout
    probe = cli(
        "probe",
        "--machine",
        path,
        "--part",
        "coupler",
        "--quantity",
        "position",
        "--cycle",
        "--csv",
        tmp_path / "p.csv",
    )
    assert probe.returncode == 0, probe.stderr
    lines = [
        line for line in (tmp_path / "p.csv").read_text().splitlines() if not line.startswith("#")
    ]
    column = lines[0].split(",").index(f"{ROCKER}_angle_rad")
    angles = np.degrees([float(line.split(",")[column]) for line in lines[1:]])
    assert [angles.min(), angles.max()] == pytest.approx([-40.0, 5.0])
    clearance = cli(
        "clearance", "--machine", path, "--pairs", "coupler:frame", "--csv", tmp_path / "c.csv"
    )
    assert clearance.returncode == 0, clearance.stderr
    view = cli("view", "--machine", path, "--html", tmp_path / "v.html", "--frames", "20")
    assert view.returncode == 0, view.stderr
    for run in (needle, probe, clearance, view):
        assert "np.float64" not in run.stdout + run.stderr


def test_range_deg_narrows_the_inspected_travel(fourbar):
    import mechanism

    _, folder = fourbar
    machine = mechanism.load_machine(
        _description(folder, limits=(-40.0, 5.0), extra="range_deg = [-30.0, 0.0]")
    )
    assert (
        math.degrees(machine.travel.lower),
        math.degrees(machine.travel.upper),
    ) == pytest.approx((-30.0, 0.0))


def test_a_hard_stop_holds_the_stalled_motor_within_a_degree(fourbar):
    import mechanism
    from mechanism.dynamics.simulation import simulate

    _, folder = fourbar
    machine = mechanism.load_machine(_description(folder, limits=(-40.0, 5.0)))
    low, high = machine.shaft_span_rad
    result = simulate(24.0, 0.6, machine=machine, start_angle_rad=low + 0.1)
    angle = np.degrees(result.arm_angle_rad)
    end = math.degrees(high)
    assert angle[-1] > end - 0.5  # driven into the upper stop, and held there
    settled = angle[result.time_s > 0.3]
    assert np.max(np.abs(settled - end)) < 1.0
    assert result.current_A[-1] == pytest.approx(24.0 / 2.0, rel=0.05)  # stalled


def test_an_unassemblable_pose_is_said_in_degrees(fourbar):
    import mechanism
    from mechanism.errors import UserError
    from mechanism.kinematics.pose import solve_pose

    _, folder = fourbar
    machine = mechanism.load_machine(_description(folder, limits=(-40.0, 5.0)))
    with pytest.raises(UserError) as caught:
        solve_pose(machine.model, machine.data, {ROCKER: math.radians(180.0)})
    message = str(caught.value)
    assert "180 deg" in message and "np.float64" not in message and "mm open" in message


@pytest.mark.parametrize(
    "table, expected",
    [
        ('[limits."J"]\nlower_deg = 10.0\nupper_deg = -10.0\n', "must be above lower_deg"),
        ('[limits."J"]\nlower_deg = 10.0\n', "needs lower_deg and upper_deg"),
        ('[limits."J"]\nlower_deg = -10.0\nupper_mm = 3.0\n', "one pair"),
        ('[limits."J"]\nlower_rad = -1.0\nupper_deg = 3.0\n', "unknown key"),
    ],
)
def test_bad_limits_are_named(table, expected):
    import tomllib

    from mechanism.errors import UserError
    from mechanism.machine.description import parse_description

    base = (
        '[machine]\nname = "x"\nmodel = "x.xml"\n[drive]\nmotor_joint = "J"\nshaft_joint = "J"\nzero_site = "S"\n'
        '[motor]\ntype = "dc"\nresistance_ohm = 1.0\ntorque_constant_Nm_per_A = 0.1\nback_emf_V_s_per_rad = 0.1\n'
    )
    with pytest.raises(UserError, match=expected):
        parse_description(tomllib.loads(base + table))


def test_zero_site_or_zero_angle():
    import tomllib

    from mechanism.errors import UserError
    from mechanism.machine.description import parse_description

    motor = '[motor]\ntype = "dc"\nresistance_ohm = 1.0\ntorque_constant_Nm_per_A = 0.1\nback_emf_V_s_per_rad = 0.1\n'
    head = '[machine]\nname = "x"\nmodel = "x.xml"\n[drive]\nmotor_joint = "J"\nshaft_joint = "J"\n'
    described = parse_description(tomllib.loads(head + "zero_angle_deg = 12.5\n" + motor))
    assert described.zero_site is None and described.zero_angle_rad == pytest.approx(
        math.radians(12.5)
    )
    with pytest.raises(UserError, match="zero_angle_deg"):
        parse_description(tomllib.loads(head + motor))
    with pytest.raises(UserError, match="not both"):
        parse_description(tomllib.loads(head + 'zero_site = "S"\nzero_angle_deg = 1.0\n' + motor))


def test_the_shipped_press_still_turns_whole_revolutions():
    import mechanism

    machine = mechanism.load_machine("press")
    assert machine.rotates and machine.shaft_span_rad is None and machine.tables.periodic


@pytest.mark.slow
def test_init_drafts_a_mechanism_that_cannot_turn_and_every_verb_takes_the_draft(cli, tmp_path):
    """A non-Grashof four-bar (shortest + longest > the other two): no link turns a whole
    revolution. init guesses a rocking shaft, its travel as limits, and says so."""
    built = FourBar(
        crank=35.0, coupler=40.0, rocker=45.0, ground=70.0, crank_angle0=math.radians(80.0)
    )
    export = built.export(tmp_path)
    draft = tmp_path / "draft.toml"
    result = cli("init", export, "-o", draft)
    assert result.returncode == 0, result.stderr
    assert "rocks (GUESS)" in result.stdout and "travel of the shaft (GUESS)" in result.stdout
    import tomllib

    written = tomllib.loads(draft.read_text())
    shaft = written["drive"]["shaft_joint"]
    limits = written["limits"][shaft]
    assert limits["lower_deg"] < 0 < limits["upper_deg"]
    for verb in (
        ("needle", "--csv", tmp_path / "n.csv"),
        ("clearance", "--all-pairs", "--csv", tmp_path / "c.csv"),
        ("simulate", "--voltage", "5", "--duration", "0.3", "--summary"),
    ):
        run = cli(verb[0], "--machine", draft, *verb[1:])
        assert run.returncode == 0, (verb, run.stderr)


def test_a_sweep_of_a_rocker_runs_the_full_model_and_says_it_does_not_turn(fourbar):
    import mechanism

    _, folder = fourbar
    machine = mechanism.load_machine(_description(folder, limits=(-40.0, 5.0)))
    result = mechanism.sweep(
        machine, {"parameters": {"V": "voltage_V"}, "sweep": {"V": [6.0]}}, duration_s=0.5
    )
    assert result.model.startswith("full")
    row = result.table()[1]
    assert "no steady running" in row["note"]
