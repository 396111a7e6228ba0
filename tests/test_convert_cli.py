"""``mechanism convert`` as a user runs it: the summary, and one clear error line for bad input."""

import json
from pathlib import Path
import shutil

import numpy as np
import pytest

from tests.helpers.exports import Gen1Export, FourBar

BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
 <!ENTITY lol5 "&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;">
 <!ENTITY lol6 "&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;">
 <!ENTITY lol7 "&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;">
 <!ENTITY lol8 "&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;">
 <!ENTITY lol9 "&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;">
]>
<PhysicalModelingXMLFile><name>&lol9;</name></PhysicalModelingXMLFile>
"""

EXTERNAL_ENTITY = """<?xml version="1.0"?>
<!DOCTYPE foo [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<PhysicalModelingXMLFile><name>&xxe;</name></PhysicalModelingXMLFile>
"""


def _traversal(folder):
    doc = Gen1Export()
    doc.weld_to_ground(
        doc.body("base", 100, (0, 0, 0), np.eye(3) * 1e3, geometry="../../etc/passwd")
    )
    return doc.write(folder / "traversal.xml")


def _truncated(folder):
    text = FourBar().export(folder, with_geometry=False).read_text()
    path = folder / "truncated.xml"
    path.write_text(text[: len(text) // 2])
    return path


def _written(name, text):
    def make(folder):
        path = folder / name
        path.write_text(text)
        return path

    return make


def _with_sidecar(entry):
    def make(folder):
        path = FourBar().export(folder, with_geometry=False)
        coupling = {
            "name": "belt",
            "kind": "belt",
            "input": "ground--crank",
            "output": "crank--coupler",
            "ratio": 2.0,
        }
        coupling.update(entry)
        (folder / "fourbar.couplings.json").write_text(
            json.dumps({"format": "mechanism-couplings/1", "couplings": [coupling]})
        )
        return path

    return make


BAD_INPUTS = {
    "billion laughs": (_written("laughs.xml", BILLION_LAUGHS), "unsafe XML"),
    "external entity": (_written("xxe.xml", EXTERNAL_ENTITY), "unsafe XML"),
    "path traversal": (_traversal, "points outside the export folder"),
    "truncated": (_truncated, "not well-formed XML"),
    "empty": (_written("empty.xml", ""), "file is empty"),
    "unknown root": (
        _written("other.xml", "<?xml version='1.0'?><Robot><link/></Robot>"),
        "root element <Robot>",
    ),
    "missing": (lambda folder: folder / "nope.xml", "no such file"),
    "sidecar joint": (_with_sidecar({"input": "ground-crank"}), "'ground-crank' does not exist"),
    "sidecar ratio": (_with_sidecar({"ratio": "2:1"}), "'ratio' must be a number"),
}
BAD_OPTIONS = {"up axis": (["--up", "w"], "up axis 'w' is not one of")}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_gives_one_error_line_and_writes_nothing(case, tmp_path, cli_here):
    make, fragment = BAD_INPUTS[case]
    source = tmp_path / "export"
    source.mkdir()
    path = make(source)
    out = tmp_path / "out" / "model"
    result = cli_here("convert", path, "-o", out, timeout=60)  # an entity bomb would run far longer
    line = result.assert_bad_input()
    assert fragment in line, line
    assert not (tmp_path / "out").exists(), "nothing is left behind"


@pytest.mark.parametrize("case", sorted(BAD_OPTIONS))
def test_bad_option_gives_one_error_line_and_writes_nothing(case, tmp_path, cli_here):
    options, fragment = BAD_OPTIONS[case]
    path = FourBar().export(tmp_path, with_geometry=False)
    line = cli_here("convert", path, "-o", tmp_path / "out", *options).assert_bad_input()
    assert fragment in line, line
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_up_axis_sets_gravity_against_it(tmp_path, cli):
    """A Y-up CAD world (SolidWorks' default) falls along -y with --up y; the frame is kept."""
    import mujoco

    path = FourBar().export(tmp_path, with_geometry=False)
    assert cli("convert", path, "-o", tmp_path / "out", "--up", "y").returncode == 0
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "fourbar.xml"))
    assert model.opt.gravity == pytest.approx([0, -9.81, 0])
    assert cli("convert", path, "-o", tmp_path / "down", "--up=-z").returncode == 0
    assert mujoco.MjModel.from_xml_path(
        str(tmp_path / "down" / "fourbar.xml")
    ).opt.gravity == pytest.approx([0, 0, 9.81])


@pytest.mark.slow
def test_failed_conversion_leaves_an_existing_output_folder_untouched(tmp_path, cli):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    cli("convert", tmp_path / "nope.xml", "-o", out).assert_bad_input()
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]


@pytest.mark.slow
def test_summary_lists_bodies_joints_loops_mass_and_warnings(tmp_path, cli):
    source = tmp_path / "export"
    source.mkdir()
    path = FourBar().export(source)
    (source / "rocker.stl").unlink()
    result = cli("convert", path, "-o", tmp_path / "out", "--name", "bars")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith(f"wrote {tmp_path / 'out' / 'bars.xml'}")
    assert "bodies: 4" in lines and "joints: 3 (3 hinge)" in lines and "loop closures: 1" in lines
    assert "couplings: 0" in lines and "degrees of freedom: 1" in lines
    assert any(line.startswith("total mass: ") and line.endswith(" kg)") for line in lines)
    warnings = [line for line in lines if line.startswith("warning: ")]
    assert len(warnings) == 1 and "rocker.stl" in warnings[0]
    assert (tmp_path / "out" / "bars.xml").exists() and (
        tmp_path / "out" / "meshes" / "crank.stl"
    ).exists()


def test_help_explains_options_and_units(cli_here):
    result = cli_here("convert", "--help")
    assert result.returncode == 0
    text = " ".join(result.stdout.split())
    for fragment in ("--out", "--name", "--mesh-dir", "--up", "metres", "couplings.json", "m/s^2"):
        assert fragment in text


def test_legs_cli_warns_that_meshes_are_missing(shared, tmp_path, cli):
    source = tmp_path / "legs"
    shutil.copytree(shared / "cad-exports" / "legs-creo-firstgen", source)
    result = cli("convert", source / "LEGS_MECHANISM.xml", "-o", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    assert any(
        line.startswith("warning: ") and "geometry file(s) are missing" in line
        for line in result.stdout.splitlines()
    )


@pytest.mark.slow
def test_summary_prints_the_inertia_reflected_through_the_belt(tmp_path, cli):
    # Two shafts on a 8:1 belt: the arm feels I_arm + 64 I_motor (a hand calculation).
    from tests.test_converter import _belt, _two_shafts

    export = _two_shafts(tmp_path, _belt(), motor_inertia=2e3, arm_inertia=5e4)
    result = cli("convert", export, "-o", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    expected = (5e4 + 64 * 2e3) * 1e-9  # g*mm^2 -> kg*m^2
    line = next(
        l for l in result.stdout.splitlines() if l.startswith("reflected inertia at arm_shaft:")
    )
    ratio_line = next(l for l in result.stdout.splitlines() if "referred to motor (ratio 8:1)" in l)
    # 4 significant digits
    assert float(line.split(":")[1].split()[0]) == pytest.approx(expected, rel=1e-3)
    assert float(ratio_line.split()[1]) == pytest.approx(expected / 64, rel=1e-3)
    moving = next(l for l in result.stdout.splitlines() if l.startswith("moving mass:"))
    # 100 g + 300 g, the base is fixed
    assert float(moving.split()[2]) == pytest.approx(0.4, rel=1e-9)


@pytest.mark.slow
def test_a_slider_at_dead_centre_is_not_reported_as_locked(tmp_path, cli):
    # The shipped sewing machine is exported at needle top dead centre, where the needle bar
    # is instantaneously immobile; it still moves, so no lock warning.
    export = (
        Path(__file__).resolve().parent.parent
        / "assets"
        / "cad"
        / "sapphire870"
        / "export"
        / "sewing_machine.xml"
    )
    result = cli("convert", export, "-o", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    assert "cannot move" not in result.stdout
    assert "degrees of freedom: 1" in result.stdout


@pytest.mark.slow
def test_explain_names_the_mates_behind_each_joint(tmp_path, cli):
    """``--explain``: per joint, the mates (by name) it was found from and what it became."""
    from tests.helpers.quirk_exports import creo_ball_beam_rigid

    export = creo_ball_beam_rigid(tmp_path)
    plain = cli("convert", export.path, "-o", tmp_path / "plain")
    assert plain.returncode == 0, plain.stderr
    assert "from mates" not in plain.stdout
    result = cli("convert", export.path, "-o", tmp_path / "out", "--explain")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert (
        "joint SERVO--HORN (revolute): from mates PIN_S_axis, PIN_S_plane -> MJCF joint(s) SERVO--HORN"
        in lines
    )
    assert any(
        line.startswith(
            "joint ROD--HOLDER (revolute): from mates PIN_B_axis, PIN_B_plane -> closes a loop"
        )
        for line in lines
    )
    assert any(
        line.startswith("joint BEAM fixed to HOLDER by mates (weld): from mates RIGID_2 -> ")
        for line in lines
    )
    assert sum(line.startswith("joint ") and "from mates" in line for line in lines) == 6
    assert lines.index(
        next(line for line in lines if line.startswith("joint SERVO"))
    ) < lines.index(next(line for line in lines if line.startswith("warnings:"))), (
        "before the warnings"
    )
