"""Outputs as one transaction: all or nothing, the previous output kept until the new one is
whole, folders swapped atomically, and a kill at any instant of publishing leaves the old or
the new output (mechanism.files.outputs)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from mechanism.errors import UserError
from mechanism.files import outputs
from mechanism.files.outputs import atomic_dir, atomic_file, atomic_path, check_outputs, transaction

REPO = Path(__file__).resolve().parent.parent


def tree(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (hidden ones too) with its text."""
    return {
        str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def write_run(tmp_path: Path, tag: str, fail: bool = False) -> None:
    """One 'run' writing a file, a plot-like path and a folder; optionally failing at the end."""
    with transaction():
        with atomic_file(tmp_path / "table.csv") as handle:
            handle.write(f"table {tag}\n")
        with atomic_path(tmp_path / "plot.png") as tmp:
            tmp.write_text(f"plot {tag}")
        with atomic_dir(tmp_path / "report") as folder:
            (folder / "index.html").write_text(f"report {tag}")
            (folder / "sub").mkdir()
            (folder / "sub" / "a.txt").write_text(tag)
        if fail:
            raise RuntimeError("the run fails after writing everything")


def test_a_run_publishes_all_its_outputs_together(tmp_path):
    with transaction():
        with atomic_file(tmp_path / "table.csv") as handle:
            handle.write("new")
        assert not (tmp_path / "table.csv").exists(), "nothing is published before the run ends"
    assert (tmp_path / "table.csv").read_text() == "new"
    write_run(tmp_path, "one")
    assert tree(tmp_path) == {
        "table.csv": "table one\n",
        "plot.png": "plot one",
        "report/index.html": "report one",
        "report/sub/a.txt": "one",
    }


def test_a_failed_run_changes_nothing_and_leaves_no_temporary(tmp_path):
    write_run(tmp_path, "old")
    before = tree(tmp_path)
    with pytest.raises(RuntimeError):
        write_run(tmp_path, "new", fail=True)
    assert tree(tmp_path) == before
    assert hidden(tmp_path) == []


def test_a_failed_run_removes_the_folders_it_created(tmp_path):
    with pytest.raises(RuntimeError):
        with transaction():
            with atomic_file(tmp_path / "a" / "b" / "c.csv") as handle:
                handle.write("x")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_a_folder_output_never_replaces_a_file(tmp_path):
    (tmp_path / "report").write_text("my notes")
    with pytest.raises(UserError, match="not a folder"):
        with atomic_dir(tmp_path / "report"):
            pass
    assert (tmp_path / "report").read_text() == "my notes"


def test_writing_the_same_output_twice_keeps_the_last_and_no_temporary(tmp_path):
    with transaction():
        for text in ("first", "second"):
            with atomic_file(tmp_path / "x.txt") as handle:
                handle.write(text)
    assert tree(tmp_path) == {"x.txt": "second"}


def test_a_kept_folder_update_never_writes_through_to_the_old_files(tmp_path):
    folder = tmp_path / "model"
    folder.mkdir()
    (folder / "mesh.stl").write_text("old mesh")
    (folder / "notes.txt").write_text("kept")
    source = tmp_path / "new.stl"
    source.write_text("new mesh")
    old_inode = os.stat(folder / "mesh.stl").st_ino
    outputs.publish_files([(source, folder / "mesh.stl")], folder=folder)
    assert tree(folder) == {"mesh.stl": "new mesh", "notes.txt": "kept"}
    assert os.stat(folder / "mesh.stl").st_ino != old_inode


@pytest.mark.parametrize(
    "files, folders, message",
    [
        ([("--csv", "in.csv")], [], "would overwrite the input"),
        ([], [("--report", "data")], "would overwrite the input"),
        ([("--csv", "a.csv"), ("--json", "a.csv")], [], "also the output of --csv"),
        ([("--csv", "data")], [], "is a folder"),
        ([("--csv", "plain/x.csv")], [], "is a file, not a folder"),
        ([("--csv", "r/x.csv")], [("--report", "r")], "lies inside it"),
    ],
)
def test_outputs_are_checked_against_inputs_and_each_other_before_work(
    tmp_path, monkeypatch, files, folders, message
):
    monkeypatch.chdir(tmp_path)
    Path("in.csv").write_text("x")
    Path("data").mkdir()
    Path("data/rec.csv").write_text("x")
    Path("plain").write_text("x")
    with pytest.raises(UserError, match=message):
        check_outputs(
            inputs=[("rec", "in.csv"), ("rec", "data/rec.csv")], files=files, folders=folders
        )


def test_a_link_to_an_input_is_the_input(tmp_path):
    (tmp_path / "in.csv").write_text("x")
    (tmp_path / "link.csv").symlink_to(tmp_path / "in.csv")
    with pytest.raises(UserError, match="would overwrite the input"):
        check_outputs(
            inputs=[("rec", tmp_path / "in.csv")], files=[("--csv", tmp_path / "link.csv")]
        )


# -- killed while publishing ---------------------------------------------------------------------

KILLER = textwrap.dedent("""
    import sys
    from pathlib import Path
    from mechanism.files import outputs
    from tests.helpers.killing import kill_before_rename

    kill_before_rename(int(sys.argv[1]), exchange=sys.argv[2] == "exchange")
    target = Path(sys.argv[3])
    with outputs.transaction():
        with outputs.atomic_dir(target / "folder") as new:
            for name in ("a", "b", "c"):
                (new / name).write_text("new " + name)
        with outputs.atomic_file(target / "file.txt") as handle:
            handle.write("new file")
""")


def old_state(target: Path) -> None:
    (target / "folder").mkdir(parents=True)
    for name in ("a", "b", "c", "d"):
        (target / "folder" / name).write_text("old " + name)
    (target / "file.txt").write_text("old file")


@pytest.mark.parametrize("mode", ["exchange", "rename"])
def test_a_kill_at_any_instant_of_publishing_leaves_the_old_or_the_new_output(tmp_path, mode):
    new = {"a": "new a", "b": "new b", "c": "new c"}
    old = {"a": "old a", "b": "old b", "c": "old c", "d": "old d"}
    seen = set()
    for kill_at in range(8):
        target = tmp_path / f"{mode}{kill_at}"
        old_state(target)
        run = subprocess.run(
            [sys.executable, "-c", KILLER, str(kill_at), mode, str(target)],
            capture_output=True,
            text=True,
            env={**os.environ, "PYTHONPATH": str(REPO)},
        )
        killed = run.returncode != 0
        outputs.clean_leftovers(target / "folder")  # what the next run does first
        outputs.clean_leftovers(target / "file.txt")
        folder = tree(target / "folder")
        assert folder in (old, new), (kill_at, folder)
        assert (target / "file.txt").read_text() in ("old file", "new file")
        assert hidden(target) == [], (kill_at, hidden(target))
        seen.add((folder == new, killed))
        if not killed:
            assert folder == new and (target / "file.txt").read_text() == "new file"
            break
    assert (False, True) in seen and (True, True) in seen, (
        "kills before and after the folder swap were both tried"
    )


def test_files_written_inside_a_folder_being_built_can_be_read_back_at_once(tmp_path):
    with transaction():
        with atomic_dir(tmp_path / "out") as work:
            with atomic_file(work / "recording.csv") as handle:
                handle.write("time_s\n0\n")
            assert (work / "recording.csv").read_text() == "time_s\n0\n"
        assert not (tmp_path / "out").exists()
    assert tree(tmp_path / "out") == {"recording.csv": "time_s\n0\n"}
