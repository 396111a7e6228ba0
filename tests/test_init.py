"""`mechanism init` drafts a description whose guessed roles are the shipped descriptions' own,
for both shipped machines (a gen-1 sewing machine and a gen-2 press), and every verb accepts the draft."""

import tomllib

import pytest

from mechanism.machine.description import read_description
from mechanism.machine.models import shipped_description, shipped_export, shipped_model


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sapphire870", "press"])
def test_init_guesses_the_roles_the_shipped_description_names(name, cli, tmp_path):
    shipped = read_description(shipped_description(name))
    export = shipped_export(name)
    draft = tmp_path / "draft.toml"
    result = cli("init", export, "-o", draft)
    assert result.returncode == 0, result.stderr
    guessed = tomllib.loads(draft.read_text())
    assert guessed["drive"] == {
        "motor_joint": shipped.motor_joint,
        "shaft_joint": shipped.shaft_joint,
        "zero_site": shipped.zero_site,
    }
    assert guessed["tool"]["plate"] == shipped.section("tool")["plate"]
    assert "GUESS" in draft.read_text() and "TODO" in draft.read_text()
    run = cli(
        "simulate",
        "--machine",
        draft,
        "--voltage",
        "12",
        "--duration",
        "0.5",
        "--summary",
        "--reduced",
    )
    assert run.returncode == 0, run.stderr
    assert "shaft speed" in run.stdout


def test_init_refuses_to_overwrite_its_input(cli_here, tmp_path):
    export = shipped_model("press")
    copy = tmp_path / "press.xml"
    copy.write_text(export.read_text())
    line = cli_here("init", copy, "-o", copy).assert_bad_input()
    assert "input" in line


@pytest.mark.slow
def test_init_keeps_a_description_the_user_edited_unless_forced(cli, tmp_path):
    export = shipped_model("press")
    out = tmp_path / "machine.toml"
    out.write_text("# my edits\n")
    line = cli("init", export, "-o", out).assert_bad_input()
    assert "--force" in line and out.read_text() == "# my edits\n"
    result = cli("init", export, "-o", out, "--force")
    assert result.returncode == 0, result.stderr
    assert "[drive]" in out.read_text()
