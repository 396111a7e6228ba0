"""The core speaks of shaft and tool (issue 24, item 4): the sewing machine's ``needle``/``arm``
words remain only as its own names and as documented aliases, which are the very same objects,
and the ``needle`` verb writes its historical file while ``tool`` writes the same numbers under
generic names."""

import argparse
import importlib
import re

import pytest

ROOMS = [
    "dynamics",
    "files",
    "inspection",
    "kinematics",
    "machine",
    "physics",
    "sysid",
    "steppers",
    "batch",
    "converters",
    "testbench",
]
# verbs that are the sewing machine's own: the tool verb's historical name, and its zigzag check
SEWING_VERBS = {"needle", "zigzag"}
WORD = re.compile(r"(?<![a-z])(needle|arm)(s|-[a-z-]+)?(?![a-z])", re.I)


def words(name: str) -> list[str]:
    """``plot_needle`` -> [plot, needle]; ``NeedleMotion`` -> [needle, motion]."""
    return [w.lower() for w in re.findall(r"[A-Z]?[a-z]+|[A-Z]+(?![a-z])|\d+", name)]


def sewing_words(name: str) -> bool:
    return bool({"needle", "arm"} & set(words(name)))


def deprecated_aliases() -> dict[str, str]:
    from mechanism import api
    from mechanism.inspection import tool

    return {**api.DEPRECATED_ALIASES, **tool.DEPRECATED_ALIASES}


def test_words_split_names_as_the_rule_means():
    assert sewing_words("plot_needle") and sewing_words("NeedleMotion")
    assert sewing_words("arm_angle_deg") and not sewing_words("warm_s")
    assert not sewing_words("harmonic_ripple") and not sewing_words("ToolMotion")


def test_public_names_speak_of_shaft_and_tool_but_for_documented_aliases():
    """A public name (``mechanism.__all__`` or a room's) with a needle or arm word is a deprecated
    alias, listed, and the very object of its generic name in the same namespace."""
    import mechanism

    aliases = deprecated_aliases()
    for package in [mechanism] + [importlib.import_module(f"mechanism.{r}") for r in ROOMS]:
        for name in package.__all__:
            if not sewing_words(name):
                continue
            assert name in aliases, f"{package.__name__}.{name}: give it a shaft/tool name"
            generic = aliases[name]
            assert generic in package.__all__ and not sewing_words(generic), (package, name)
            assert getattr(package, name) is getattr(package, generic), (package, name)


def test_the_old_names_stay_importable_and_are_the_new_objects():
    import mechanism
    from mechanism import api
    from mechanism.inspection import needle, tool

    assert mechanism.needle_motion is mechanism.tool_motion is tool.tool_motion
    assert mechanism.NeedleMotion is mechanism.ToolMotion is tool.ToolMotion
    assert mechanism.plot_needle is mechanism.plot_tool_motion is tool.plot
    assert mechanism.write_needle_csv is mechanism.write_tool_motion_csv is tool.write_csv
    assert needle.needle_motion is tool.tool_motion and needle.write_csv is tool.write_csv
    assert mechanism.inspection.NeedleMotion is mechanism.inspection.ToolMotion
    for old, new in api.DEPRECATED_ALIASES.items():
        assert getattr(mechanism, old) is getattr(mechanism, new), old


def test_the_motions_old_field_names_read_and_write_the_new_fields():
    import numpy as np

    from mechanism.inspection.tool import FIELD_ALIASES, ToolMotion

    n = 4
    motion = ToolMotion(
        *(np.arange(n, dtype=float) + k for k in range(6)),
        stroke_mm=1.0,
        tdc_angle_deg=0.0,
        bdc_angle_deg=180.0,
        tdc_z_mm=1.0,
        bdc_z_mm=0.0,
        plate_reference="the world origin",
        speed_rpm=60.0,
    )
    for old, new in FIELD_ALIASES.items():
        value = getattr(motion, new)
        assert getattr(motion, old) is value or getattr(motion, old) == value, old
    motion.needle_rise_at_passage_mm = 2.5
    assert motion.tool_rise_at_passage_mm == 2.5
    assert motion.arm_speed_rad_s == pytest.approx(2 * np.pi)
    needle, tool = motion.columns("needle"), motion.columns("tool")
    assert list(needle)[:2] == ["arm_angle_deg", "needle_z_mm"]
    assert list(tool)[:2] == ["shaft_angle_deg", "tool_z_mm"]
    assert all(np.array_equal(a, b) for a, b in zip(needle.values(), tool.values()))
    assert list(motion.columns()) == list(needle)  # the historical names stay the default


def _verbs() -> dict[str, argparse.ArgumentParser]:
    from mechanism.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    summaries = {action.dest: action.help or "" for action in sub._choices_actions}
    return {name: (p, summaries.get(name, "")) for name, p in sub.choices.items()}


def prose_words(text: str) -> list[str]:
    """The needle/arm words of help ``text`` outside quotes and outside names: a token with ``_``,
    ``:`` or ``.`` in it, or an option (``--no-needle``), names a column, part or option, which
    keep the sewing machine's spelling (docs/architecture.md)."""
    text = re.sub(r"'[^'\n]*'", " ", text)
    found = []
    for token in text.split():
        token = token.strip('()[]{},;"')
        if token.startswith("-") or any(c in token for c in "_:.=/"):
            continue
        found += [m.group(0) for m in WORD.finditer(token)]
    return found


def test_prose_words_finds_what_it_should():
    assert prose_words("one arm revolution, the needle-bar height") == ["arm", "needle-bar"]
    assert prose_words("--no-needle, arm_angle [rad], needle:hook, 'mechanism needle'") == []
    assert prose_words("warm up, harmonics, arms") == ["arms"]


def test_no_generic_verb_speaks_of_needle_or_arm():
    """Outside the sewing machine's own verbs, no verb name, no one-line summary (``mechanism
    --help``) and no help text (``mechanism VERB --help``) uses needle or arm as a word."""
    verbs = _verbs()
    assert "tool" in verbs and "needle" in verbs
    wrong = {}
    for name, (parser, summary) in verbs.items():
        if name in SEWING_VERBS:
            continue
        found = prose_words(name.replace("-", " ")) + prose_words(summary)
        found += prose_words(parser.format_help())
        if found:
            wrong[name] = found
    assert not wrong, wrong


@pytest.mark.slow
def test_the_tool_verb_writes_the_needle_verbs_numbers_under_generic_names(tmp_path, cli):
    import numpy as np

    from mechanism.files.tables import read_table
    from mechanism.inspection.tool import COLUMN_NAMES

    args = ("--samples", "72", "--speed", "600")
    needle = cli("needle", "--csv", tmp_path / "needle.csv", *args)
    tool = cli("tool", "--csv", tmp_path / "tool.csv", *args)
    assert needle.returncode == 0 and tool.returncode == 0, needle.stderr + tool.stderr
    assert needle.stdout.replace("needle.csv", "X") == tool.stdout.replace("tool.csv", "X")
    old = (tmp_path / "needle.csv").read_text().splitlines()
    new = (tmp_path / "tool.csv").read_text().splitlines()
    assert (
        old[0] == "# needle motion over one arm revolution (arm angle 0 = needle top dead centre)"
    )
    assert (
        new[0] == "# tool motion over one shaft revolution (shaft angle 0 = needle_tip at its top)"
    )
    assert (
        old[1:] != new[1:]
        and [x for x in old if x.startswith("# ")][1:] == [x for x in new if x.startswith("# ")][1:]
    )
    header = [line for line in old if not line.startswith("#")][0].split(",")
    assert header == [historical for _, historical in COLUMN_NAMES]
    a = read_table(tmp_path / "needle.csv", required=header)
    b = read_table(tmp_path / "tool.csv", required=[generic for generic, _ in COLUMN_NAMES])
    for generic, historical in COLUMN_NAMES:
        np.testing.assert_array_equal(a[historical], b[generic])


@pytest.mark.parametrize("verb", ["tool", "needle"])
@pytest.mark.parametrize("args", [("--samples", "5"), ("--speed", "-100")])
def test_both_verbs_refuse_bad_input_alike(tmp_path, cli_here, verb, args):
    csv = tmp_path / "t.csv"
    line = cli_here(verb, "--csv", csv, *args).assert_bad_input()
    assert not csv.exists() and line.startswith("error:")
