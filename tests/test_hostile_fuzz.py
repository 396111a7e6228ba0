"""Property-based hostile inputs (hypothesis): recordings, variant files, machine descriptions
and CAD exports (XML and STL bytes) generated at random, each verb held to the contract:
exit 0 with a complete output, or exit 2 with one ``error:`` line; never a traceback or
third-party text; the inputs unchanged; nothing half-written and no temporary left.

The verbs run in this process (``mechanism.cli.main``) to keep a hundred runs within seconds;
``max_examples`` is small so the whole file stays well under a minute."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, example, given, settings, strategies as st  # noqa: E402

from tests.helpers.exports import FourBar  # noqa: E402
from mechanism.cli import main  # noqa: E402
from mechanism.errors import UserError  # noqa: E402

FUZZ = settings(
    max_examples=12,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

hostile_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, -1.0, 1e-300, 1e300, -1e300, 1e38, float("nan"), float("inf")]),
    st.floats(min_value=-100, max_value=100),
)
cells = st.one_of(
    hostile_floats.map(repr),
    st.sampled_from(["", " ", "x", "1,2", '"', "0x10", "1e999", "\x00", "é"]),
)


def run(capfd, *args) -> tuple[int, str]:
    capfd.readouterr()
    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:  # argparse
        code = exc.code
    return code, capfd.readouterr().err


def snapshot(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def assert_contract(code: int, stderr: str, out: Path, expect_on_success=()) -> None:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert "Traceback" not in stderr, stderr
    assert all(line.startswith(("error:", "warning:")) for line in lines), stderr
    if code == 2:
        assert sum(line.startswith("error:") for line in lines) == 1, stderr
        assert not out.exists() or not any(out.iterdir()), sorted(p.name for p in out.iterdir())
    else:
        assert code == 0, (code, stderr)
        for name in expect_on_success:
            assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    if out.exists():
        assert not [p for p in out.rglob(".*")], "temporaries left"


# -- recordings ---------------------------------------------------------------------------------


@st.composite
def recordings(draw) -> str:
    names = draw(
        st.lists(
            st.sampled_from(
                [
                    "time",
                    "time_s",
                    "voltage",
                    "voltage_V",
                    "arm_angle",
                    "shaft_angle",
                    "current",
                    "junk",
                ]
            ),
            min_size=0,
            max_size=5,
        )
    )
    width = len(names)
    rows = draw(
        st.lists(st.lists(cells, min_size=max(width - 1, 0), max_size=width + 1), max_size=30)
    )
    comments = draw(
        st.lists(st.text(max_size=20).map(lambda t: "# " + t.replace("\n", " ")), max_size=2)
    )
    return "\n".join([*comments, ",".join(names), *(",".join(r) for r in rows)]) + "\n"


@FUZZ
@given(text=recordings())
def test_identify_holds_the_contract_on_any_recording(tmp_path_factory, capfd, text):
    folder = tmp_path_factory.mktemp("rec")
    recording = folder / "rec.csv"
    recording.write_text(text, encoding="utf-8")
    out = folder / "out"
    code, stderr = run(capfd, "identify", recording, "--json", out / "fit.json")
    assert_contract(code, stderr, out)
    assert code == 2  # under 30 rows of 1 s at most: never enough to identify
    assert recording.read_text(encoding="utf-8") == text


# -- variant files (library: read before any model is touched) ------------------------------------

json_values = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(10**12), 10**12),
        hostile_floats,
        st.text(max_size=12),
    ),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4)
    ),
    max_leaves=20,
)


@st.composite
def variant_documents(draw):
    params = draw(
        st.dictionaries(
            st.sampled_from(["a", "b", "timing"]),
            st.one_of(
                st.none(), st.sampled_from(["body:x:x_mm", "coupling:c:j_deg", "bad"]), json_values
            ),
            max_size=3,
        )
    )
    axis = st.one_of(
        st.lists(hostile_floats, max_size=4),
        st.fixed_dictionaries(
            {"start": hostile_floats, "stop": hostile_floats, "num": st.integers(-5, 10**6)}
        ),
        json_values,
    )
    document = {
        "format": draw(st.sampled_from(["mechanism-variants/1", "x"])),
        "parameters": params,
    }
    if draw(st.booleans()):
        document["sweep"] = draw(
            st.dictionaries(st.sampled_from(["a", "b", "timing"]), axis, max_size=3)
        )
    if draw(st.booleans()):
        document["samples"] = draw(
            st.one_of(
                json_values,
                st.fixed_dictionaries(
                    {
                        "count": st.integers(-1, 10**7),
                        "seed": st.integers(-1, 5),
                        "tolerances": st.dictionaries(
                            st.sampled_from(["a", "b"]), json_values, max_size=2
                        ),
                    }
                ),
            )
        )
    return document


@FUZZ
@given(document=variant_documents())
def test_variant_files_are_read_or_refused_in_one_line(tmp_path_factory, document):
    import json

    from mechanism.inspection.variants import MAX_VARIANTS, read_variants

    path = tmp_path_factory.mktemp("variants") / "v.json"
    path.write_text(json.dumps(document))
    try:
        variants = read_variants(path)
    except UserError as exc:
        assert "\n" not in str(exc)
        return
    assert len(variants) <= MAX_VARIANTS
    assert all(math.isfinite(v) for v in variants.values.ravel())


# -- machine descriptions -----------------------------------------------------------------------

NUMBER_KEYS = [
    "resistance_ohm",
    "torque_constant_Nm_per_A",
    "back_emf_V_s_per_rad",
    "series_resistance_ohm",
    "voltage_V",
    "timestep_ms",
]


def shipped_description() -> str:
    from mechanism.machine.models import DEFAULT_DESCRIPTION

    text = Path(DEFAULT_DESCRIPTION).read_text()
    model = re.search(r'^model = "([^"]+)"', text, re.M)[1]
    return text.replace(
        f'model = "{model}"', f'model = "{(Path(DEFAULT_DESCRIPTION).parent / model).resolve()}"'
    )


def toml_number(value: float) -> str:
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return repr(value)


@pytest.mark.slow
@FUZZ
@given(key=st.sampled_from(NUMBER_KEYS), value=hostile_floats)
@example(key="back_emf_V_s_per_rad", value=1e-300)  # once a MuJoCo ValueError
@example(key="resistance_ohm", value=1.5)  # a legal one: exit 0 with finite results
def test_simulate_holds_the_contract_on_any_motor_or_supply_number(
    tmp_path_factory, capfd, key, value
):
    folder = tmp_path_factory.mktemp("machine")
    text = re.sub(
        rf"^{key} = [^\n#]*",
        f"{key} = {toml_number(value)} ",
        shipped_description(),
        count=1,
        flags=re.M,
    )
    description = folder / "m.toml"
    description.write_text(text)
    out = folder / "out"
    code, stderr = run(
        capfd,
        "simulate",
        "--machine",
        description,
        "--voltage",
        "12",
        "--duration",
        "0.02",
        "--csv",
        out / "run.csv",
    )
    assert_contract(code, stderr, out, expect_on_success=["run.csv"])
    if code == 0:
        data = (out / "run.csv").read_text()
        assert "nan" not in data.lower() and "inf" not in data.lower()


# -- CAD exports: XML and STL bytes ----------------------------------------------------------------


@pytest.fixture(scope="module")
def clean_export(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("fourbar")
    FourBar().export(folder)
    return folder


NUMBER = re.compile(rb"-?\d+(\.\d+)?(e-?\d+)?")


@st.composite
def mutated_exports(draw, original: dict[str, bytes]):
    files = dict(original)
    name = draw(st.sampled_from(sorted(files)))
    data = files[name]
    how = draw(st.sampled_from(["number", "truncate", "bytes", "stl-floats"]))
    if how == "number" and name.endswith(".xml"):
        matches = list(NUMBER.finditer(data))
        match = matches[draw(st.integers(0, len(matches) - 1))]
        data = (
            data[: match.start()] + toml_number(draw(hostile_floats)).encode() + data[match.end() :]
        )
    elif how == "truncate":
        data = data[: draw(st.integers(0, len(data)))]
    elif how == "stl-floats" and name.endswith(".stl") and len(data) > 84 + 50:
        start = 84 + 12 + 50 * draw(st.integers(0, (len(data) - 84) // 50 - 1))
        import struct

        data = data[:start] + struct.pack("<f", draw(st.floats(width=32))) + data[start + 4 :]
    else:
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(max_size=16)) + data[at:]
    files[name] = data
    return files


@pytest.mark.slow
@FUZZ
@given(data=st.data())
def test_convert_holds_the_contract_on_any_damaged_export(
    tmp_path_factory, capfd, clean_export, data
):
    files = data.draw(mutated_exports(snapshot(clean_export)))
    folder = tmp_path_factory.mktemp("export")
    for name, content in files.items():
        (folder / name).write_bytes(content)
    out = folder.parent / f"{folder.name}-out"
    code, stderr = run(capfd, "convert", folder / "fourbar.xml", "-o", out)
    assert_contract(code, stderr, out, expect_on_success=["fourbar.xml"])
    assert snapshot(folder) == files
    shutil.rmtree(out, ignore_errors=True)


# -- recording files in every format (issue 26) -----------------------------------------------


def _valid_recording_files(folder: Path) -> dict[str, bytes]:
    """One small valid recording per reader, written by the format's own library."""
    import bz2
    import gzip
    import io
    import json
    import zipfile

    import numpy as np
    import scipy.io

    t = np.arange(300) / 100.0
    columns = {"time": t, "voltage": np.where(t < 1.5, 3.0, 9.0), "arm_angle": 2.0 * t}
    text = (
        "time,voltage,arm_angle\n"
        + "\n".join(",".join(f"{c[i]:.6g}" for c in columns.values()) for i in range(len(t)))
        + "\n"
    )
    files = {
        ".csv.gz": gzip.compress(text.encode()),
        ".csv.bz2": bz2.compress(text.encode()),
        ".json": json.dumps(
            [dict(zip(columns, map(float, row))) for row in zip(*columns.values())]
        ).encode(),
    }
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("r.csv", text)
    files[".zip"] = buffer.getvalue()
    for compress in (False, True):
        buffer = io.BytesIO()
        scipy.io.savemat(buffer, {"rec": columns}, do_compression=compress)
        files[".mat" if compress else "_plain.mat"] = buffer.getvalue()
    try:
        import pyarrow as pa
        import pyarrow.feather as feather
        import pyarrow.parquet as pq

        buffer = io.BytesIO()
        pq.write_table(pa.table(columns), buffer)
        files[".parquet"] = buffer.getvalue()
        buffer = io.BytesIO()
        feather.write_feather(pa.table(columns), buffer)
        files[".feather"] = buffer.getvalue()
    except ImportError:
        pass
    try:
        import nptdms

        buffer = io.BytesIO()
        with nptdms.TdmsWriter(buffer) as writer:
            writer.write_segment([nptdms.ChannelObject("g", k, v) for k, v in columns.items()])
        files[".tdms"] = buffer.getvalue()
    except ImportError:
        pass
    return files


_VALID: dict[str, bytes] = {}


@settings(FUZZ, max_examples=80)
@given(data=st.data())
def test_every_reader_refuses_damaged_files_in_one_line(tmp_path_factory, data):
    """A valid file of each format, truncated and with bytes overwritten: read, or one UserError."""
    from mechanism.files.formats import read_columns

    folder = tmp_path_factory.mktemp("damaged")
    if not _VALID:
        _VALID.update(_valid_recording_files(folder))
    ending = data.draw(st.sampled_from(sorted(_VALID)))
    raw = bytearray(_VALID[ending])
    cut = data.draw(st.integers(0, len(raw)))
    for _ in range(data.draw(st.integers(0, 6))):
        at = data.draw(st.integers(0, max(0, len(raw) - 1)))
        if raw:
            raw[at] = data.draw(st.integers(0, 255))
    path = folder / ("r" + ending.replace("_plain", ""))
    path.write_bytes(bytes(raw[:cut] if data.draw(st.booleans()) else raw))
    try:
        read_columns(path)
    except UserError as exc:
        assert "\n" not in str(exc) and "Traceback" not in str(exc)
