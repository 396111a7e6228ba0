"""The shared plumbing every verb relies on: CSV input checks, atomic outputs, CLI errors."""

import json
import os

import numpy as np
import pytest

from mechanism.errors import UserError
from mechanism.files.outputs import atomic_dir, atomic_file
from mechanism.data.reference import thesis
from mechanism.files.tables import check_increasing, parse_table, read_table, write_table

from tests.conftest import shared_dir


def test_table_reads_comments_header_and_ignores_unknown_columns():
    table = parse_table(
        "# layers: 12\n# free text\ntime,voltage,extra\n0,1,x\n0.001,2,y\n", ["time", "voltage"]
    )
    assert table.metadata == {"layers": "12"}
    np.testing.assert_allclose(table["voltage"], [1, 2])
    assert "extra" not in table


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("", "empty"),
        ("time,voltage\n0,nan\n", "NaN/inf"),
        ("time,voltage\n0,abc\n", "not a number"),
        ("time\n0\n", "missing required column(s) voltage"),
        ("time,voltage\n0,1,2\n", "has 3 fields"),
        ("time,voltage\n", "0 data row"),
    ],
)
def test_table_rejects_malformed_input_with_one_clear_message(text, fragment):
    with pytest.raises(UserError, match=None) as info:
        parse_table(text, ["time", "voltage"])
    assert fragment in str(info.value)
    assert "\n" not in str(info.value)


def test_increasing_time_check_names_the_row():
    with pytest.raises(UserError, match="duplicated at data row 3"):
        check_increasing(np.array([0.0, 1.0, 1.0]), "rec")
    check_increasing(np.array([0.0, 1.0, 2.0]), "rec")


def test_written_table_round_trips_with_units_in_names(tmp_path):
    path = write_table(
        tmp_path / "out.csv", {"time_s": [0, 0.5], "needle_z_mm": [1.25, -3]}, comments=["model: x"]
    )
    table = read_table(path, ["time_s", "needle_z_mm"])
    assert table.metadata == {"model": "x"}
    np.testing.assert_allclose(table["needle_z_mm"], [1.25, -3])


def test_missing_table_file_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="no such file"):
        read_table(tmp_path / "nope.csv")


def test_atomic_dir_leaves_nothing_on_failure_and_replaces_on_success(tmp_path):
    target = tmp_path / "out" / "model"
    with pytest.raises(RuntimeError):
        with atomic_dir(target) as tmp:
            (tmp / "half.xml").write_text("<mujoco")
            raise RuntimeError("boom")
    assert not target.exists()
    assert not (tmp_path / "out").exists(), "a parent created for the output must be removed again"
    with atomic_dir(target) as tmp:
        (tmp / "model.xml").write_text("<mujoco/>")
    assert (target / "model.xml").read_text() == "<mujoco/>"
    assert os.listdir(target.parent) == ["model"]


def test_atomic_file_keeps_the_old_file_when_writing_fails(tmp_path):
    target = tmp_path / "a.json"
    target.write_text("old")
    with pytest.raises(ValueError):
        with atomic_file(target) as handle:
            handle.write("new")
            raise ValueError
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["a.json"]


def test_reference_copy_is_identical_to_the_shared_file():
    shared = shared_dir()
    if shared is None:
        pytest.skip("shared folder not present")
    assert thesis() == json.loads((shared / "reference" / "tegsten2008.json").read_text())


def test_unknown_verb_and_bad_option_give_one_error_line(cli_here):
    cli_here("no-such-verb").assert_bad_input()
    result = cli_here()
    assert result.returncode == 2


def test_outputs_get_ordinary_permissions_not_mkstemp_private_ones(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_file(tmp_path / "a.csv") as handle:
            handle.write("x")
        with atomic_dir(tmp_path / "d"):
            pass
    finally:
        os.umask(old)
    assert (tmp_path / "a.csv").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "d").stat().st_mode & 0o777 == 0o755
