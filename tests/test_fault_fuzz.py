"""Property-based faults (hypothesis): every verb that writes, a full disk, a quota, a file size
limit, Ctrl-C or SIGTERM injected at a random write event of its run and its publishing
(tests/helpers/faults.py). The contract each time: a disk fault is exit 2 with one ``error:``
line naming the output folder and the cause, the previous outputs byte for byte; a signal is
exit 130/143 with one ``error: interrupted`` line and the outputs all old, or (a signal that came
while publishing, which waits for it, and finds the run complete) exit 0 and all new; never a
temporary, a lock or a traceback.

The verbs run in this process (``mechanism.cli.main``); ``max_examples`` is small (each example
is one run, about a second) and the file is marked slow. ``demo`` (over a minute a run) is left
out: it writes through the same atomic folder as ``convert`` and the fleet."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

from mechanism.cli import main  # noqa: E402
from tests.helpers.faults import FAULTS, injected  # noqa: E402

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parent.parent
EXPORT = REPO / "assets" / "cad" / "sapphire870" / "export" / "sewing_machine.xml"
FUZZ = settings(
    max_examples=10,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

# verb -> (arguments with {out}, {recording}, {variants}; the outputs it writes: files, or folders ending in /)
VERBS = {
    "simulate": (
        [
            "simulate",
            "--voltage",
            "12",
            "--duration",
            "0.3",
            "--csv",
            "{out}/run.csv",
            "--plot",
            "{out}/run.png",
        ],
        ["run.csv", "run.png"],
    ),
    "needle": (["needle", "--samples", "90", "--csv", "{out}/needle.csv"], ["needle.csv"]),
    "tool": (
        ["tool", "--samples", "90", "--csv", "{out}/tool.csv", "--plot", "{out}/tool.png"],
        ["tool.csv", "tool.png"],
    ),
    "probe": (
        [
            "probe",
            "--part",
            "needle_tip",
            "--quantity",
            "position",
            "--cycle",
            "--csv",
            "{out}/probe.csv",
        ],
        ["probe.csv"],
    ),
    "clearance": (
        ["clearance", "--pairs", "needle:hook", "--csv", "{out}/c.csv", "--json", "{out}/c.json"],
        ["c.csv", "c.json"],
    ),
    "view": (["view", "--frames", "10", "--html", "{out}/view.html"], ["view.html"]),
    "convert": (["convert", str(EXPORT), "-o", "{out}/model"], ["model/"]),
    # --force: the previous description is there on purpose (init keeps an edited one otherwise)
    "init": (["init", str(EXPORT), "-o", "{out}/machine.toml", "--force"], ["machine.toml"]),
    "sweep": (
        ["sweep", "--variants", "{variants}", "--duration", "0.5", "--csv", "{out}/sweep.csv"],
        ["sweep.csv"],
    ),
    "testbench": (
        ["testbench", "--effect", "none", "--duration", "2.5", "-o", "{out}/rec.csv"],
        ["rec.csv"],
    ),
    "stepper": (
        ["stepper", "--sequence", "thread-cut", "--csv", "{out}/st.csv", "--json", "{out}/st.json"],
        ["st.csv", "st.json"],
    ),
    "zigzag": (
        ["zigzag", "--spm", "1000", "--rate", "1000", "--stitches", "2", "--json", "{out}/z.json"],
        ["z.json"],
    ),
    "identify": (["identify", "{recording}", "--json", "{out}/identify.json"], ["identify.json"]),
    "diagnose": (["diagnose", "{recording}", "--json", "{out}/diagnosis.json"], ["diagnosis.json"]),
    "fleet": (["diagnose", "{recording}", "{recording2}", "--out", "{out}/fleet"], ["fleet/"]),
}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A cache of its own, two bench recordings and a variants file, outside the fault's folder."""
    folder = tmp_path_factory.mktemp("inputs")
    patch = pytest.MonkeyPatch()
    patch.setenv("MECHANISM_CACHE", str(folder / "cache"))
    for name, seed in (("rec.csv", "1"), ("rec2.csv", "2")):
        assert (
            main(
                [
                    "testbench",
                    "--effect",
                    "none",
                    "--duration",
                    "3",
                    "--seed",
                    seed,
                    "-o",
                    str(folder / name),
                ]
            )
            == 0
        )
    (folder / "variants.csv").write_text("voltage_V\n8\n12\n")
    yield {
        "recording": str(folder / "rec.csv"),
        "recording2": str(folder / "rec2.csv"),
        "variants": str(folder / "variants.csv"),
    }
    patch.undo()


def arguments(verb: str, out: Path, inputs: dict) -> list[str]:
    return [a.format(out=out, **inputs) for a in VERBS[verb][0]]


def old_outputs(out: Path, verb: str) -> dict[str, bytes]:
    """The previous outputs the run must not lose: a file, or a folder with a file in it."""
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    for name in VERBS[verb][1]:
        if name.endswith("/"):
            (out / name).mkdir()
            (out / name / "old.txt").write_text("old folder content")
        else:
            (out / name).write_text("old output")
    return snapshot(out)


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file, but a sweep's journal (OUT.csv.partial): kept on purpose, for --resume."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.name.endswith(".partial")
    }


def part(files: dict[str, bytes], output: str) -> dict[str, bytes]:
    """The files of one output (a file, or a folder's files) in a snapshot."""
    return {name: data for name, data in files.items() if name == output or name.startswith(output)}


def leftovers(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob(".*"))


_new: dict[str, tuple[int, dict[str, bytes]]] = {}


def new_run(verb: str, out: Path, inputs: dict) -> tuple[int, dict[str, bytes]]:
    """How many write events the verb's whole run has, and the outputs it leaves (once per verb)."""
    if verb not in _new:
        old_outputs(out, verb)
        with injected(out, 10**9, "ENOSPC") as counter:
            code = main(arguments(verb, out, inputs))
        assert code in (0, 1), (verb, code)
        _new[verb] = (counter.events, snapshot(out))
    return _new[verb]


@FUZZ
@given(verb=st.sampled_from(sorted(VERBS)), fault=st.sampled_from(FAULTS), where=st.floats(0, 1))
def test_a_fault_at_a_random_write_keeps_the_contract(tmp_path, capfd, inputs, verb, fault, where):
    out = tmp_path / f"out-{verb}"
    events, new = new_run(verb, out, inputs)
    before = old_outputs(out, verb)
    fail_at = min(events - 1, int(where * events))
    capfd.readouterr()
    with injected(out, fail_at, fault) as injector:
        code = main(arguments(verb, out, inputs))
    err = capfd.readouterr().err
    lines = [line for line in err.splitlines() if line.strip() and "%|" not in line]
    errors = [line for line in lines if line.startswith("error:")]
    assert injector.fired, (verb, fail_at, events)
    assert "Traceback" not in err, err
    assert all(line.startswith(("error:", "warning:")) for line in lines), err
    assert leftovers(out) == [], (verb, fault, fail_at, leftovers(out))
    if fault.startswith("SIG"):
        kept = {
            output: part(snapshot(out), output) == part(before, output) for output in VERBS[verb][1]
        }
        if injector.fired_publishing:  # the signal came while the run published: it is complete
            assert code == 0 and errors == [] and not any(kept.values()), (verb, fault, kept)
            assert set(snapshot(out)) == set(new), (verb, fault, fail_at)
        else:
            assert code == (130 if fault == "SIGINT" else 143), (verb, fail_at, err)
            assert errors == ["error: interrupted"], err
            assert all(kept.values()), (verb, fault, fail_at, kept)
            assert set(snapshot(out)) == set(before), (verb, fault, fail_at)
    else:
        assert code == 2, (verb, fault, fail_at, err)
        cause = {"ENOSPC": "disk is full", "EDQUOT": "quota", "EFBIG": "file size limit"}[fault]
        assert len(errors) == 1 and cause in errors[0] and str(out) in errors[0], (
            verb,
            fail_at,
            err,
        )
        assert snapshot(out) == before, (verb, fault, fail_at)
