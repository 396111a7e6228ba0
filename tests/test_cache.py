"""The cache of converted exports and compiled kernels (mechanism.files.cache): entries checked
by the hash of their content at each use, rebuilt with a warning when truncated, edited,
foreign or half-written; bounded in size; emptied by ``mechanism cache clear``."""

from __future__ import annotations

import json
import os
import shutil
import time
import warnings
from pathlib import Path

import pytest

from tests.helpers.exports import FourBar
from mechanism.files import cache
from mechanism.machine.models import converted_model


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch) -> Path:
    monkeypatch.setenv("MECHANISM_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("MECHANISM_CACHE_MAX_MB", raising=False)
    return tmp_path / "cache" / "mechanism"


def convert_quietly(export: Path) -> tuple[Path, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mjcf = converted_model(export)
    return mjcf, [str(w.message) for w in caught]


def entry_files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def truncate(entry: Path, other: Path) -> None:
    mjcf = next(entry.glob("*.xml"))
    mjcf.write_bytes(mjcf.read_bytes()[:100])


def edit(entry: Path, other: Path) -> None:
    mjcf = next(entry.glob("*.xml"))
    mjcf.write_text(mjcf.read_text().replace("<mujoco", "<mujoco ", 1))


def half_written(entry: Path, other: Path) -> None:
    (entry / cache.MANIFEST).unlink()  # a crash before the entry was sealed


def foreign(entry: Path, other: Path) -> None:
    """Another export's whole entry (its own manifest included) under this entry's name."""
    shutil.rmtree(entry)
    shutil.copytree(other, entry)


@pytest.mark.parametrize(
    "damage", [truncate, edit, half_written, foreign], ids=lambda f: f.__name__
)
def test_a_damaged_model_entry_is_rebuilt_with_a_warning(tmp_path, damage):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    export = FourBar().export(tmp_path / "a")
    other_export = FourBar(crank=25.0).export(tmp_path / "b")
    mjcf, first = convert_quietly(export)
    other, _ = convert_quietly(other_export)
    assert first == [] and mjcf.parent != other.parent
    whole = entry_files(mjcf.parent)
    assert cache.MANIFEST in whole
    again, quiet = convert_quietly(export)
    assert again == mjcf and quiet == []  # a whole entry is used as it is
    damage(mjcf.parent, other.parent)
    rebuilt, said = convert_quietly(export)
    assert rebuilt == mjcf
    assert len(said) == 1 and "rebuilding" in said[0] and str(mjcf.parent) in said[0], said
    assert entry_files(mjcf.parent) == whole
    # no temporary, no lock
    assert not [p for p in mjcf.parent.parent.iterdir() if p.name.startswith(".")]


def test_a_damaged_compiled_kernel_is_rebuilt_with_a_warning(own_cache):
    from mechanism import native

    native.load.cache_clear()
    if native.load("machine") is None:
        pytest.skip("no C compiler")
    (library,) = (own_cache / "native").glob("libmachine-*.so")
    assert cache.file_problem(library) is None
    library.write_bytes(library.read_bytes()[:1000])  # truncated
    native.load.cache_clear()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert native.load("machine") is not None
    assert any("truncated or edited" in str(w.message) for w in caught), [
        str(w.message) for w in caught
    ]
    assert cache.file_problem(library) is None
    native.load.cache_clear()


def make_entry(root: Path, name: str, size: int, age_s: float) -> Path:
    folder = root / "models" / name
    folder.mkdir(parents=True)
    (folder / "model.xml").write_bytes(b"x" * size)
    cache.seal_folder(folder, name)
    stamp = time.time() - age_s
    os.utime(folder, (stamp, stamp))
    return folder


def test_the_cache_is_bounded_and_drops_the_least_recently_used_first(own_cache, monkeypatch):
    old = make_entry(own_cache, "old", 600_000, 300)
    middle = make_entry(own_cache, "middle", 600_000, 200)
    new = make_entry(own_cache, "new", 600_000, 100)
    monkeypatch.setenv("MECHANISM_CACHE_MAX_MB", "1.0")
    assert cache.prune(keep=old) == 2  # the one just built stays, however old its stamp
    assert old.exists() and not middle.exists() and not new.exists()
    assert cache.info().bytes <= 2**20


@pytest.mark.slow
def test_cache_clear_empties_the_cache_in_one_line(own_cache, cli, tmp_path):
    make_entry(own_cache, "one", 1000, 10)
    (own_cache / "native").mkdir()
    (own_cache / "native" / "libx-0.so").write_bytes(b"\0" * 10)
    env = {"MECHANISM_CACHE": str(tmp_path / "cache")}
    shown = cli("cache", "info", env=env)
    assert (
        shown.returncode == 0 and "2 entries" in shown.stdout and str(own_cache) in shown.stdout
    ), shown.stdout
    cleared = cli("cache", "clear", env=env)
    assert cleared.returncode == 0 and cleared.stderr == "", cleared.stderr
    assert "removed 2 entries" in cleared.stdout
    assert not (own_cache / "models").exists() and not (own_cache / "native").exists()
    assert "0 entries" in cli("cache", "info", env=env).stdout


def test_a_manifest_records_the_hash_of_every_file(own_cache):
    folder = make_entry(own_cache, "entry", 10, 0)
    document = json.loads((folder / cache.MANIFEST).read_text())
    assert document["key"] == "entry" and set(document["files"]) == {"model.xml"}
    assert cache.folder_problem(folder, "entry") is None
    assert "foreign" in cache.folder_problem(folder, "another key")
    (folder / "extra.stl").write_bytes(b"solid")
    assert "added" in cache.folder_problem(folder, "entry")
