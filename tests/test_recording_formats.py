"""Recordings as benches write them (issue 26): every reader on small real files written at
run time by the tools' own libraries (scipy.io.savemat, h5py, pyarrow, npTDMS, gzip, zipfile,
json), each with its own column names and units and a [recording] map back to the contract;
the expression parser; the map's precedence; gaps; the test bench's formats round-trip;
hostile files (truncated, wrong types, huge declared sizes, bombs) as one error line."""

from __future__ import annotations

import bz2
import gzip
import json
import lzma
import math
import sys
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest

from mechanism.errors import UserError
from mechanism.sysid.recording import read_recording
from mechanism.sysid.recording_map import (
    RecordingMap,
    parse_expression,
    read_recording_map,
    resolve_recording_map,
)

FS = 1000.0
COUNTS = 4096
TWO_PI = 2 * math.pi


@pytest.fixture(scope="module")
def truth():
    """A recording in contract units: voltage steps, a quantised angle turning both ways, current."""
    rng = np.random.default_rng(26)
    t = np.arange(int(4 * FS)) / FS
    u = np.where(t < 1, 4.0, np.where(t < 2, 12.0, np.where(t < 3, -40.0, 30.0))) + rng.normal(
        0, 0.01, t.size
    )
    speed = np.cumsum(u) / FS * 3.0
    angle = np.floor(np.cumsum(speed) / FS / (TWO_PI / COUNTS)) * (TWO_PI / COUNTS) + 2 * TWO_PI
    current = 0.1 * u + rng.normal(0, 0.01, t.size)
    return {"time": t, "voltage": u, "angle": angle, "current": current}


def map_file(folder: Path, text: str) -> Path:
    path = folder / "map.toml"
    path.write_text("[recording]\n" + text)
    return path


def check_same(rec, truth, angle_tol=1e-9, shift=0.0):
    assert len(rec) == len(truth["time"])
    assert np.allclose(rec.time_s - rec.time_s[0], truth["time"] - truth["time"][0], atol=1e-9)
    assert np.allclose(rec.voltage_V, truth["voltage"], atol=1e-6)
    assert np.allclose(rec.arm_angle_rad, truth["angle"] + shift, atol=angle_tol)


def csv_text(truth, names=("time", "voltage", "arm_angle", "current"), sep=","):
    rows = [sep.join(names)] + [
        sep.join(f"{v:.12g}" for v in row)
        for row in zip(truth["time"], truth["voltage"], truth["angle"], truth["current"])
    ]
    return "# counts_per_rev: 4096\n" + "\n".join(rows) + "\n"


@pytest.mark.parametrize(
    "name, pack",
    [
        ("r.csv.gz", lambda b: gzip.compress(b)),
        ("r.csv.bz2", lambda b: bz2.compress(b)),
        ("r.csv.xz", lambda b: lzma.compress(b)),
        ("r.csv", lambda b: b),
    ],
)
def test_compressed_csv_reads_as_the_plain_one(tmp_path, truth, name, pack):
    path = tmp_path / name
    path.write_bytes(pack(csv_text(truth).encode()))
    rec = read_recording(path)
    check_same(rec, truth)
    assert rec.metadata["counts_per_rev"] == "4096"
    assert rec.reading["file_format"] == "csv" + name[len("r.csv") :]


def test_a_zip_of_one_tsv_with_other_names_and_degrees(tmp_path, truth):
    text = csv_text(
        {**truth, "angle": np.degrees(truth["angle"])},
        names=("t_ms", "U", "enc_deg", "I"),
        sep="\t",
    )
    lines = text.splitlines()
    lines[2:] = [
        "\t".join([f"{float(c.split(chr(9))[0]) * 1e3:.9g}", *c.split("\t")[1:]]) for c in lines[2:]
    ]
    path = tmp_path / "r.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("bench/run1.tsv", "\n".join(lines) + "\n")
    mapping = map_file(
        tmp_path,
        'time = "t_ms"\ntime_unit = "ms"\nvoltage = "U"\nshaft_angle = "enc_deg"\n'
        'shaft_angle_unit = "deg"\ncurrent = "I"\n',
    )
    rec = read_recording(path, mapping)
    check_same(rec, truth, angle_tol=1e-8)
    assert np.allclose(rec.current_A, truth["current"], atol=1e-9)


def test_matlab_v5_ball_screw_in_metres_with_a_flipped_sign_and_an_offset(tmp_path, truth):
    import scipy.io

    lead_mm = 2.5
    metres = -(truth["angle"] - 0.25) / TWO_PI * lead_mm * 1e-3  # the bench counts the other way
    path = tmp_path / "bench.mat"
    scipy.io.savemat(
        path,
        {
            "t": truth["time"].reshape(-1, 1),
            "Umot": truth["voltage"].reshape(-1, 1),
            "sig": {"x_screw": metres.reshape(-1, 1)},
            "note": "dSPACE run 3",
        },
    )
    mapping = map_file(
        tmp_path,
        'time = "t"\nvoltage = "Umot"\nshaft_angle = "sig.x_screw"\nshaft_angle_unit = "m"\n'
        "travel_per_rev_mm = 2.5\ndirection = -1\noffset_rad = 0.25\n",
    )
    rec = read_recording(path, mapping)
    check_same(rec, truth, angle_tol=1e-9)
    assert rec.reading["shaft_angle_rad"]["direction"] == -1
    assert rec.reading["shaft_angle_rad"]["rad_per_unit"] == pytest.approx(TWO_PI / 2.5e-3)


def test_matlab_v73_through_h5py(tmp_path, truth):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "bench73.mat"
    with h5py.File(path, "w", userblock_size=512) as handle:
        for name, values in (
            ("time", truth["time"]),
            ("volts", truth["voltage"]),
            ("rev", truth["angle"] / TWO_PI),
        ):
            # MATLAB stores a column transposed
            handle.create_dataset(name, data=values.reshape(1, -1))
            handle[name].attrs["MATLAB_class"] = np.bytes_("double")
    with open(path, "r+b") as handle:
        handle.write(b"MATLAB 7.3 MAT-file, written by a test".ljust(116, b" "))
    mapping = map_file(
        tmp_path, 'voltage = "volts"\nshaft_angle = "rev"\nshaft_angle_unit = "rev"\n'
    )
    check_same(read_recording(path, mapping), truth, angle_tol=1e-9)


def test_parquet_and_feather_through_pyarrow(tmp_path, truth):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.feather as feather
    import pyarrow.parquet as pq

    counts = np.round((truth["angle"]) / (TWO_PI / COUNTS)).astype(np.int64)
    table = pa.table(
        {
            "ts_us": (truth["time"] * 1e6).astype(np.int64),
            "u_V": truth["voltage"],
            "enc": counts,
            "label": ["run"] * len(counts),
        }
    )
    pq.write_table(table, tmp_path / "r.parquet")
    feather.write_feather(table, tmp_path / "r.feather")
    mapping = map_file(
        tmp_path,
        'time = "ts_us"\ntime_unit = "us"\nvoltage = "u_V"\nshaft_angle = "enc"\n'
        'shaft_angle_unit = "counts"\ncounts_per_rev = 4096\n',
    )
    for name in ("r.parquet", "r.feather"):
        rec = read_recording(tmp_path / name, mapping)
        check_same(rec, truth, angle_tol=1e-9)
        assert rec.metadata["counts_per_rev"] == "4096"


def test_labview_tdms_with_wrapping_encoder_counts(tmp_path, truth):
    nptdms = pytest.importorskip("nptdms")
    counts = np.round(truth["angle"] / (TWO_PI / COUNTS)).astype(np.int64)
    wrapped = (counts % COUNTS).astype(np.int32)
    path = tmp_path / "r.tdms"
    with nptdms.TdmsWriter(path) as writer:
        writer.write_segment(
            [
                nptdms.ChannelObject("Motor", "Time", truth["time"]),
                nptdms.ChannelObject("Motor", "Voltage", truth["voltage"]),
                nptdms.ChannelObject("Motor", "Encoder", wrapped),
            ]
        )
    mapping = map_file(
        tmp_path,
        'time = "Motor/Time"\nvoltage = "`Motor/Voltage` * 1"\nshaft_angle = "Encoder"\n'
        'shaft_angle_unit = "counts"\ncounts_per_rev = 4096\nunwrap = true\n',
    )
    rec = read_recording(path, mapping)
    turns = np.floor(counts[0] / COUNTS) * TWO_PI  # unwrapping keeps the first sample's turn
    check_same(rec, truth, angle_tol=1e-9, shift=-turns)
    assert rec.reading["shaft_angle_rad"]["unwrapped"].startswith("yes")


def servo_log(truth, rate_hz=190.0, seed=1):
    """A smart servo's JSON log: ms time stamps with jitter, position in counts, the voltage as
    an unsigned 16-bit PWM register (two's complement) times the supply / 885."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(
        np.full(int(4 * rate_hz), 1 / rate_hz) * (1 + rng.uniform(-0.2, 0.2, int(4 * rate_hz)))
    )
    t = t[t < truth["time"][-1]]
    supply = 12.0
    u = np.interp(t, truth["time"], truth["voltage"])
    load = np.round(u * 885 / supply).astype(int)
    position = np.round(np.interp(t, truth["time"], truth["angle"]) / (TWO_PI / COUNTS)).astype(int)
    entries = [
        {
            "timestamp": 1.7e12 + 1e3 * ti,
            "position": int(p),
            "load": int(lo % 65536),
            "input_volts": supply,
            "mode": "pwm",
        }
        for ti, p, lo in zip(t, position, load)
    ]
    return t, load * supply / 885, position * TWO_PI / COUNTS, entries


SERVO_MAP = (
    'records = "entries"\ntime = "timestamp"\ntime_unit = "ms"\nsigned_bits = { load = 16 }\n'
    'voltage = "load * input_volts / 885"\nshaft_angle = "position"\nshaft_angle_unit = "counts"\n'
    "counts_per_rev = 4096\n"
)


def test_a_servo_json_log_with_jitter_is_resampled_and_says_how(tmp_path, truth):
    t, volts, angle, entries = servo_log(truth)
    (tmp_path / "servo.json").write_text(json.dumps({"device": "servo 1", "entries": entries}))
    (tmp_path / "servo.jsonl").write_text("\n".join(json.dumps(e) for e in entries) + "\n")
    mapping = map_file(tmp_path, SERVO_MAP)
    rec = read_recording(tmp_path / "servo.json", mapping)
    assert np.min(volts) < 0  # the log held negative voltages as 16-bit registers
    assert rec.reading["resampling"]["rate_Hz"] == pytest.approx(190, rel=0.05)
    assert "zero-order hold" in rec.reading["resampling"]["method"]
    assert rec.reading["time_s"]["shifted_by_s"] == pytest.approx(-(1.7e9 + t[0]), rel=1e-12)
    # on the grid: the angle is the log's interpolated linearly, the voltage the last logged value
    grid = rec.time_s
    stamps = np.array([e["timestamp"] for e in entries])
    logged = (stamps - stamps[0]) / 1000  # the log's own times, as rounded in it
    assert np.allclose(rec.arm_angle_rad, np.interp(grid, logged, angle), atol=1e-6)
    last = np.searchsorted(logged, grid + 1e-6 * rec.dt, side="right") - 1
    assert np.allclose(rec.voltage_V, volts[last], atol=1e-9)
    mapping_lines = map_file(tmp_path, SERVO_MAP.replace('records = "entries"\n', ""))
    other = read_recording(tmp_path / "servo.jsonl", mapping_lines)
    assert np.allclose(other.arm_angle_rad, rec.arm_angle_rad) and np.allclose(
        other.voltage_V, rec.voltage_V
    )


def test_signed_bits_turn_registers_into_twos_complement(tmp_path):
    t = np.arange(3000) / FS
    register = np.where(t < 1.5, 65535, 1)  # -1, then +1
    path = tmp_path / "r.csv"
    path.write_text(
        "t,reg,pos\n" + "\n".join(f"{a:.4f},{r},{a * 5:.6f}" for a, r in zip(t, register)) + "\n"
    )
    rec = read_recording(
        path,
        map_file(
            tmp_path,
            'time = "t"\nsigned_bits = { reg = 16 }\nvoltage = "reg * 2"\nshaft_angle = "pos"\n',
        ),
    )
    assert set(np.unique(rec.voltage_V)) == {-2.0, 2.0}
    path.write_text(path.read_text().replace(",65535,", ",70000,", 1))
    with pytest.raises(UserError, match="unsigned 16-bit"):
        read_recording(
            path,
            map_file(
                tmp_path,
                'time = "t"\nsigned_bits = { reg = 16 }\nvoltage = "reg"\nshaft_angle = "pos"\n',
            ),
        )


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os').system('true')",
        "a + b",
        "a.real()",
        "a ** 2",
        "(a * 2).real",
        "a if b else c",
        "[a]",
        "lambda: a",
        "a[0]",
        "'a'",
        "True * a",
    ],
)
def test_expressions_other_than_products_and_quotients_are_refused(text):
    with pytest.raises(UserError, match="only products and quotients|neither a column"):
        parse_expression(text, "map")


def test_a_product_and_a_quotient_with_backquoted_names_evaluate(tmp_path):
    t = np.arange(2500) / FS
    path = tmp_path / "r.csv"
    path.write_text(
        "time,pwm (%),supply V,pos\n"
        + "\n".join(f"{a:.4f},{50 + a},{24},{a:.4f}" for a in t)
        + "\n"
    )
    rec = read_recording(
        path, map_file(tmp_path, 'voltage = "-`pwm (%)` * `supply V` / 100"\nshaft_angle = "pos"\n')
    )
    assert np.allclose(rec.voltage_V, -(50 + t) * 24 / 100)


def test_the_map_file_wins_over_the_descriptions_table(tmp_path):
    from mechanism.machine.description import parse_description
    from mechanism.machine.models import DEFAULT_DESCRIPTION

    data = tomllib.loads(Path(DEFAULT_DESCRIPTION).read_text())
    data["recording"] = {"shaft_angle": "deg_col", "shaft_angle_unit": "deg"}
    description = parse_description(data, "test", Path(DEFAULT_DESCRIPTION).parent)
    assert resolve_recording_map(description, None).table["shaft_angle"] == "deg_col"
    mapping = resolve_recording_map(description, map_file(tmp_path, 'shaft_angle = "rad_col"\n'))
    assert mapping.table == {"shaft_angle": "rad_col"}
    assert resolve_recording_map(None, None) is None


@pytest.mark.parametrize(
    "text, fragment",
    [
        ('shaft_angel = "x"\n', "did you mean"),
        ('shaft_angle_unit = "counts"\n', "needs counts_per_rev"),
        ('shaft_angle_unit = "mm"\n', "needs travel_per_rev_mm"),
        ("direction = 0\n", "1 or -1"),
        ('time_unit = "min"\n', "not one of"),
        ('voltage = "a + b"\n', "only products and quotients"),
        ("signed_bits = { load = 1 }\n", "out of range"),
    ],
)
def test_bad_maps_are_one_line(tmp_path, text, fragment):
    with pytest.raises(UserError) as info:
        read_recording_map(map_file(tmp_path, text))
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_a_gap_is_refused_naming_its_time_and_inspect_lists_it(tmp_path, cli_here, truth):
    keep = (truth["time"] < 1.5) | (truth["time"] > 1.8)
    part = {k: v[keep] for k, v in truth.items()}
    path = tmp_path / "gap.csv"
    path.write_text(csv_text(part))
    with pytest.raises(UserError, match=r"after t = 1\.499 s"):
        read_recording(path)
    result = cli_here("inspect-recording", path, "--json", tmp_path / "i.json")
    assert "after t = 1.499 s" in result.assert_bad_input()
    data = json.loads((tmp_path / "i.json").read_text())
    assert data["gaps"][0]["after_s"] == pytest.approx(1.499) and data["gaps"][0][
        "length_s"
    ] == pytest.approx(0.302)


@pytest.mark.slow
def test_inspect_recording_reports_units_rate_encoder_and_excitation(tmp_path, cli, truth):
    path = tmp_path / "r.csv.gz"
    path.write_bytes(gzip.compress(csv_text(truth).encode()))
    result = cli("inspect-recording", path, "--json", tmp_path / "i.json")
    assert result.returncode == 0, result.stderr
    data = json.loads((tmp_path / "i.json").read_text())
    assert data["rate_Hz"] == pytest.approx(FS)
    assert data["encoder"]["counts_per_rev_detected"] == COUNTS
    assert data["ranges"]["voltage_V"]["min"] == pytest.approx(truth["voltage"].min())
    assert data["excitation"]["coulomb_friction"]["excited"]  # it turns both ways
    assert data["excitation"]["turns_backward"] and data["excitation"]["turns_forward"]
    assert "4096 counts/rev" in result.stdout
    # turns per second
    top = np.percentile(np.abs(np.gradient(truth["angle"], 1 / FS)), 99) / TWO_PI
    assert data["nyquist_Hz"] == pytest.approx(FS / 2)
    assert data["orders_per_turn_visible_at_top_speed"] == pytest.approx(FS / 2 / top, rel=0.05)
    # one constant voltage: not identifiable, said per parameter
    flat = {**truth, "voltage": np.full_like(truth["voltage"], 6.0)}
    path.write_bytes(gzip.compress(csv_text(flat).encode()))
    cli("inspect-recording", path, "--json", tmp_path / "i.json")
    data = json.loads((tmp_path / "i.json").read_text())
    assert not data["identifiable"] and not data["excitation"]["inertia"]["excited"]


@pytest.mark.slow
def test_the_test_bench_writes_every_format_it_reads(tmp_path, cli):
    reference = None
    for fmt in ("csv", "csv.gz", "parquet", "mat"):
        path = tmp_path / f"rec.{fmt}"
        result = cli(
            "testbench", "--effect", "none", "--duration", "3", "--format", fmt, "-o", path
        )
        assert result.returncode == 0, result.stderr
        rec = read_recording(path)
        assert rec.metadata["counts_per_rev"] == "20000"
        if reference is None:
            reference = rec
            continue
        assert np.allclose(rec.arm_angle_rad, reference.arm_angle_rad, atol=1e-8)
        assert np.allclose(rec.voltage_V, reference.voltage_V, atol=1e-8)
        assert np.allclose(rec.current_A, reference.current_A, atol=1e-8)
    assert (
        "ends as a csv file"
        in cli(
            "testbench", "--effect", "none", "--format", "mat", "-o", tmp_path / "x.csv"
        ).assert_bad_input()
    )


@pytest.mark.slow
def test_identify_on_a_mat_file_with_a_map_gives_the_csvs_fit_and_says_what_was_done(tmp_path, cli):
    import scipy.io

    csv_path = tmp_path / "rec.csv"
    assert cli("testbench", "--effect", "none", "--duration", "8", "-o", csv_path).returncode == 0
    rec = read_recording(csv_path)
    scipy.io.savemat(
        tmp_path / "rec.mat",
        {
            "t": rec.time_s,
            "u": rec.voltage_V,
            "enc": -np.round(rec.arm_angle_rad / (TWO_PI / 20000)),
        },
    )
    mapping = map_file(
        tmp_path,
        'time = "t"\nvoltage = "u"\nshaft_angle = "enc"\nshaft_angle_unit = "counts"\n'
        "counts_per_rev = 20000\ndirection = -1\n",
    )
    out = {}
    for name, extra in (("csv", []), ("mat", ["--recording-map", mapping])):
        source = csv_path if name == "csv" else tmp_path / "rec.mat"
        result = cli("identify", source, *extra, "--json", tmp_path / f"{name}.json")
        assert result.returncode == 0, result.stderr
        out[name] = json.loads((tmp_path / f"{name}.json").read_text())
    assert out["mat"]["rmse"] == pytest.approx(out["csv"]["rmse"], rel=0.01)
    for key, value in out["csv"]["params"].items():
        assert out["mat"]["params"][key] == pytest.approx(value, rel=0.01)
    assert out["mat"]["reading"]["shaft_angle_rad"]["direction"] == -1
    assert (
        "counts" in out["mat"]["reading"]["shaft_angle_rad"]["formula"]
        or out["mat"]["reading"]["shaft_angle_rad"]["unit"] == "counts"
    )


# -- hostile files -------------------------------------------------------------------------------


def _truncated(tmp_path, truth, name):
    path = tmp_path / name
    if name.endswith(".gz"):
        data = gzip.compress(csv_text(truth).encode())
    elif name.endswith(".mat"):
        import scipy.io

        scipy.io.savemat(
            path, {"time": truth["time"], "voltage": truth["voltage"], "arm_angle": truth["angle"]}
        )
        data = path.read_bytes()
    elif name.endswith(".parquet"):
        pa = pytest.importorskip("pyarrow")
        import pyarrow.parquet as pq

        pq.write_table(
            pa.table(
                {"time": truth["time"], "voltage": truth["voltage"], "arm_angle": truth["angle"]}
            ),
            path,
        )
        data = path.read_bytes()
    elif name.endswith(".tdms"):
        nptdms = pytest.importorskip("nptdms")
        with nptdms.TdmsWriter(path) as writer:
            writer.write_segment(
                [
                    nptdms.ChannelObject("g", n, truth[k])
                    for n, k in (("time", "time"), ("voltage", "voltage"), ("arm_angle", "angle"))
                ]
            )
        data = path.read_bytes()
    elif name.endswith(".zip"):
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("r.csv", csv_text(truth))
        data = path.read_bytes()
    else:
        data = json.dumps(
            [
                {"time": a, "voltage": b, "arm_angle": c}
                for a, b, c in zip(truth["time"], truth["voltage"], truth["angle"])
            ]
        ).encode()
    path.write_bytes(data[: len(data) // 2])
    return path


@pytest.mark.parametrize("name", ["r.csv.gz", "r.mat", "r.parquet", "r.tdms", "r.zip", "r.json"])
def test_truncated_files_are_one_error_line(tmp_path, cli_here, truth, name):
    path = _truncated(tmp_path, truth, name)
    line = cli_here("inspect-recording", path).assert_bad_input()
    assert any(word in line for word in ("truncated", "not a readable", "not valid", "corrupt")), (
        line
    )


def test_wrong_types_are_one_error_line(tmp_path, cli_here, truth):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    pq.write_table(
        pa.table({"time": ["soon"] * 10, "voltage": [1.0] * 10, "arm_angle": [0.0] * 10}),
        tmp_path / "r.parquet",
    )
    assert (
        "not a number" in cli_here("inspect-recording", tmp_path / "r.parquet").assert_bad_input()
    )
    (tmp_path / "r.json").write_text(json.dumps({"entries": [1, 2, 3]}))
    assert (
        "record 1"
        in cli_here(
            "inspect-recording",
            tmp_path / "r.json",
            "--recording-map",
            map_file(tmp_path, 'records = "entries"\n'),
        ).assert_bad_input()
    )
    import scipy.io

    scipy.io.savemat(tmp_path / "r.mat", {"time": "a string", "voltage": np.ones(5)})
    assert (
        "missing required column(s) time"
        in cli_here("inspect-recording", tmp_path / "r.mat").assert_bad_input()
    )
    (tmp_path / "r.csv.gz").write_bytes(b"not gzip at all")
    assert ".gz" in cli_here("inspect-recording", tmp_path / "r.csv.gz").assert_bad_input()


@pytest.mark.slow
def test_a_mat_file_declaring_huge_dimensions_is_refused_before_allocating(tmp_path, cli):
    import scipy.io

    path = tmp_path / "huge.mat"
    scipy.io.savemat(path, {"time": np.arange(4.0)}, do_compression=False)
    data = bytearray(path.read_bytes())
    assert int.from_bytes(data[160:164], "little") in (1, 4)  # the dimensions of the first matrix
    data[160:168] = (100_000).to_bytes(4, "little") + (100_000).to_bytes(4, "little")
    path.write_bytes(bytes(data))
    assert "MECHANISM_MAX_ELEMENTS" in cli("inspect-recording", path).assert_bad_input()


@pytest.mark.slow
def test_a_parquet_file_with_too_many_rows_for_the_element_limit_is_refused(tmp_path, cli, truth):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    pq.write_table(
        pa.table({"time": truth["time"], "voltage": truth["voltage"], "arm_angle": truth["angle"]}),
        tmp_path / "r.parquet",
    )
    line = cli(
        "inspect-recording", tmp_path / "r.parquet", env={"MECHANISM_MAX_ELEMENTS": "1000"}
    ).assert_bad_input()
    assert "MECHANISM_MAX_ELEMENTS" in line


@pytest.mark.slow
def test_zip_and_gzip_bombs_stop_at_the_input_limit(tmp_path, cli):
    zeros = b"0" * (3 << 20)  # 3 MiB of text that compresses to a few KiB
    with zipfile.ZipFile(tmp_path / "bomb.zip", "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("r.csv", zeros)
    (tmp_path / "bomb.csv.gz").write_bytes(gzip.compress(zeros))
    for name in ("bomb.zip", "bomb.csv.gz"):
        assert (tmp_path / name).stat().st_size < 100_000
        line = cli(
            "inspect-recording", tmp_path / name, env={"MECHANISM_MAX_INPUT_MB": "1"}
        ).assert_bad_input()
        assert "input limit of 1 MiB" in line
    with zipfile.ZipFile(tmp_path / "two.zip", "w") as archive:
        archive.writestr("a.csv", "time\n")
        archive.writestr("b.csv", "time\n")
    assert "exactly one file" in cli("inspect-recording", tmp_path / "two.zip").assert_bad_input()


def test_a_missing_optional_library_names_the_extra(tmp_path, truth, monkeypatch):
    path = tmp_path / "r.tdms"
    path.write_bytes(b"TDSm")
    monkeypatch.setitem(sys.modules, "nptdms", None)  # import nptdms now raises ImportError
    with pytest.raises(UserError) as info:
        read_recording(path)
    assert str(info.value) == "reading .tdms needs npTDMS: pip install 'mechanism[tdms]'"
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    (tmp_path / "r.parquet").write_bytes(b"PAR1")
    with pytest.raises(UserError, match=r"pip install 'mechanism\[parquet\]'"):
        read_recording(tmp_path / "r.parquet")


def test_an_unknown_ending_is_refused_listing_the_known_ones(tmp_path):
    (tmp_path / "r.xlsx").write_bytes(b"PK")
    with pytest.raises(UserError, match=r"unknown file type.*\.mat"):
        read_recording(tmp_path / "r.xlsx")


def test_recording_map_object_is_accepted_as_is(tmp_path, truth):
    path = tmp_path / "r.csv"
    path.write_text(csv_text(truth, names=("T", "V", "A", "I")))
    rec = read_recording(
        path,
        RecordingMap({"time": "T", "voltage": "V", "shaft_angle": "A", "current": "I"}, "code"),
    )
    check_same(rec, truth)


def test_the_readmes_column_maps_are_valid_maps(tmp_path):
    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    blocks = [block.split("```", 1)[0] for block in readme.split("```toml")[1:]]
    maps = [b for b in blocks if "[recording]" in b]
    assert len(maps) >= 5  # one per format
    for block in maps:
        text = "\n".join(
            line.strip() for line in block.splitlines() if not line.strip().startswith("#")
        )
        path = tmp_path / "m.toml"
        path.write_text(text)
        assert read_recording_map(path).table  # every key known, every value in range


def test_matrix_columns_headerless_text_and_json_quirks(tmp_path, truth):
    import scipy.io

    # one N x 3 matrix (t, u, y): its columns by MATLAB's 1-based name or numpy's 0-based one
    scipy.io.savemat(
        tmp_path / "m.mat",
        {"data": np.column_stack([truth["time"], truth["voltage"], truth["angle"]])},
    )
    for names in (("data(:,1)", "data(:,2)", "data(:,3)"), ("data[:, 0]", "data[1]", "data(3)")):
        mapping = map_file(tmp_path, 'time = "%s"\nvoltage = "%s"\nshaft_angle = "%s"\n' % names)
        check_same(read_recording(tmp_path / "m.mat", mapping), truth)
    # a headerless whitespace table: col1, col2, ...
    rows = "\n".join(
        f"{a:.12g}  {b:.12g}\t{c:.12g}"
        for a, b, c in zip(truth["time"], truth["voltage"], truth["angle"])
    )
    (tmp_path / "r.dat").write_text(rows.replace("\t", "  ") + "\n")
    check_same(
        read_recording(
            tmp_path / "r.dat",
            map_file(tmp_path, 'time = "col1"\nvoltage = "col2"\nshaft_angle = "col3"\n'),
        ),
        truth,
    )
    # semicolons and decimal commas, as a European spreadsheet writes them
    rows = "\n".join(
        f"{a:.12g};{b:.12g};{c:.12g}".replace(".", ",")
        for a, b, c in zip(truth["time"], truth["voltage"], truth["angle"])
    )
    (tmp_path / "r.csv").write_text("time;voltage;arm_angle\n" + rows + "\n")
    check_same(read_recording(tmp_path / "r.csv"), truth)
    # JSON: the one list of records found without records =, numbers as text, ISO time stamps
    stamps = [f"2026-11-26T17:00:{t:09.6f}+00:00" for t in truth["time"]]
    entries = [
        {"t": s, "v": str(u), "pos": {"rad": a}}
        for s, u, a in zip(stamps, truth["voltage"], truth["angle"])
    ]
    (tmp_path / "r.json").write_text(json.dumps({"meta": {"rate": 1000}, "log": entries}))
    rec = read_recording(
        tmp_path / "r.json",
        map_file(tmp_path, 'time = "t"\nvoltage = "v"\nshaft_angle = "pos.rad"\n'),
    )
    check_same(rec, truth, angle_tol=1e-9)
    doubled = read_recording(
        tmp_path / "r.json",
        map_file(tmp_path, 'time = "t"\nvoltage = "v"\nshaft_angle = "pos.rad * 2 / 2"\n'),
    )
    # a nested field inside an expression
    assert np.array_equal(doubled.arm_angle_rad, rec.arm_angle_rad)
    # a record without a field: named when the field is used
    del entries[7]["v"]
    (tmp_path / "r.json").write_text(json.dumps(entries))
    with pytest.raises(UserError, match="column v: missing from record 8"):
        read_recording(
            tmp_path / "r.json",
            map_file(tmp_path, 'time = "t"\nvoltage = "v"\nshaft_angle = "pos.rad"\n'),
        )


def test_a_mapped_log_reads_as_its_hand_conversion_whatever_the_time_stamps(tmp_path, truth):
    """The same servo log as JSON (epoch ms) through the map, and hand-converted to CSV with
    relative or epoch seconds: the same grid, voltage and angle (the grid's step must not
    depend on how the stamps were rounded; the median step did, by half a sample a minute)."""
    _, _, _, entries = servo_log(truth, seed=4)
    (tmp_path / "servo.json").write_text(json.dumps({"entries": entries}))
    rec = read_recording(tmp_path / "servo.json", map_file(tmp_path, SERVO_MAP))
    stamps = np.array([e["timestamp"] for e in entries])
    load = np.array([e["load"] for e in entries])
    volts = np.where(load >= 32768, load - 65536, load) * 12.0 / 885
    angle = np.array([e["position"] for e in entries]) * TWO_PI / COUNTS
    for seconds in ((stamps - stamps[0]) / 1000, stamps / 1000):
        rows = "\n".join(
            f"{float(a)!r},{float(b)!r},{float(c)!r}" for a, b, c in zip(seconds, volts, angle)
        )
        (tmp_path / "hand.csv").write_text("time,voltage,arm_angle\n" + rows + "\n")
        hand = read_recording(tmp_path / "hand.csv")
        # epoch seconds hold 2.4e-7 s
        assert len(hand) == len(rec) and hand.dt == pytest.approx(rec.dt, rel=1e-7)
        assert np.array_equal(hand.voltage_V, rec.voltage_V)
        assert np.allclose(hand.arm_angle_rad, rec.arm_angle_rad, atol=1e-9)


@pytest.mark.slow
def test_split_cuts_at_the_gaps_into_pieces_a_fleet_reads(tmp_path, cli):
    t = np.arange(12000) / FS
    # 3 gaps; 0.1 s is too short
    keep = (t < 3.0) | ((t >= 3.3) & (t < 3.4)) | ((t >= 4.0) & (t < 8.0)) | (t >= 9.0)
    counts = np.floor(7.0 * t / (TWO_PI / COUNTS))
    part = {
        "time": t[keep],
        "voltage": np.where(t < 6, 5.0, 9.0)[keep],
        "angle": (counts * TWO_PI / COUNTS)[keep],
        "current": np.full(int(keep.sum()), 0.3),
    }
    path = tmp_path / "gappy.csv"
    path.write_text(csv_text(part))
    result = cli(
        "inspect-recording", path, "--split", tmp_path / "pieces", "--json", tmp_path / "i.json"
    )
    assert result.returncode == 0, result.stderr
    assert len(json.loads((tmp_path / "i.json").read_text())["gaps"]) == 3
    pieces = sorted((tmp_path / "pieces").glob("*.csv"))
    assert [p.name for p in pieces] == ["gappy_part1.csv", "gappy_part3.csv", "gappy_part4.csv"]
    first, middle, last = (read_recording(p) for p in pieces)
    assert first.time_s[-1] == pytest.approx(2.999) and np.allclose(
        first.arm_angle_rad, part["angle"][part["time"] < 3]
    )
    assert middle.time_s[0] == pytest.approx(4.0) and len(middle) == 4000
    assert last.time_s[0] == pytest.approx(9.0) and last.metadata["counts_per_rev"] == "4096"


def test_a_tdms_waveform_gives_its_time_track(tmp_path, truth):
    nptdms = pytest.importorskip("nptdms")
    path = tmp_path / "wave.tdms"
    dt = 1 / FS
    with nptdms.TdmsWriter(path) as writer:
        writer.write_segment(
            [
                nptdms.ChannelObject(
                    "Bench", name, values, properties={"wf_increment": dt, "wf_start_offset": 0.0}
                )
                for name, values in (
                    ("U", truth["voltage"]),
                    ("theta_deg", np.degrees(truth["angle"])),
                )
            ]
        )
    mapping = map_file(
        tmp_path,
        'time = "Bench/U.time"\nvoltage = "U"\nshaft_angle = "theta_deg"\nshaft_angle_unit = "deg"\n',
    )
    check_same(read_recording(path, mapping), truth, angle_tol=1e-9)


def test_the_public_api_reads_and_inspects_with_a_map(tmp_path, truth):
    import mechanism

    path = tmp_path / "r.csv"
    path.write_text(csv_text(truth, names=("T", "V", "A", "I")))
    mapping = map_file(tmp_path, 'time = "T"\nvoltage = "V"\nshaft_angle = "A"\ncurrent = "I"\n')
    check_same(mechanism.read_recording(path, recording_map=mapping), truth)
    data = mechanism.inspect_recording(path, recording_map=mapping)
    assert (
        data["chosen"]["voltage_V"]["from"] == "V"
        and data["usable"]
        and data["samples"] == len(truth["time"])
    )
    with pytest.raises(UserError, match="missing required column"):
        mechanism.read_recording(path)


@pytest.mark.slow
def test_inspect_takes_the_descriptions_table_and_the_map_file_wins(tmp_path, cli, truth):
    import re

    from mechanism.machine.models import DEFAULT_DESCRIPTION

    text = Path(DEFAULT_DESCRIPTION).read_text()
    model_line = next(line for line in text.splitlines() if line.startswith("model"))
    model = (Path(DEFAULT_DESCRIPTION).parent / re.search(r'"([^"]+)"', model_line)[1]).resolve()
    text = text.replace(model_line, f'model = "{model}"')
    description = tmp_path / "m.toml"
    description.write_text(
        text
        + '\n[recording]\ntime = "T"\nvoltage = "V"\nshaft_angle = "A_deg"\nshaft_angle_unit = "deg"\n'
    )
    path = tmp_path / "r.csv"
    degrees = {**truth, "angle": np.degrees(truth["angle"])}
    path.write_text(csv_text(degrees, names=("T", "V", "A_deg", "I")))
    result = cli("inspect-recording", path, "--machine", description, "--json", tmp_path / "a.json")
    assert result.returncode == 0, result.stderr
    by_description = json.loads((tmp_path / "a.json").read_text())
    assert (
        by_description["map"].startswith("machine description")
        and by_description["chosen"]["shaft_angle_rad"]["unit"] == "deg"
    )
    assert by_description["ranges"]["shaft_angle_rad"]["max"] == pytest.approx(truth["angle"].max())
    # says rad: wrong, but it wins
    wins = map_file(tmp_path, 'time = "T"\nvoltage = "V"\nshaft_angle = "A_deg"\n')
    cli(
        "inspect-recording",
        path,
        "--machine",
        description,
        "--recording-map",
        wins,
        "--json",
        tmp_path / "b.json",
    )
    by_file = json.loads((tmp_path / "b.json").read_text())
    assert (
        by_file["map"].startswith("recording map")
        and by_file["chosen"]["shaft_angle_rad"]["unit"] == "rad"
    )
    assert by_file["ranges"]["shaft_angle_rad"]["max"] == pytest.approx(
        np.degrees(truth["angle"]).max()
    )


@pytest.mark.slow
def test_a_mat_file_whose_compressed_variable_inflates_past_the_limit_is_refused(tmp_path, cli):
    import scipy.io

    path = tmp_path / "bomb.mat"
    scipy.io.savemat(
        path, {"s": {"time": np.zeros(400_000), "voltage": np.zeros(400_000)}}, do_compression=True
    )
    # 6.4 MB of zeros inside a struct (whose size whosmat does not see)
    assert path.stat().st_size < 100_000
    line = cli("inspect-recording", path, env={"MECHANISM_MAX_INPUT_MB": "1"}).assert_bad_input()
    assert "inflates past the input limit of 1 MiB" in line


def test_even_epoch_stamps_give_the_grid_of_relative_ones(tmp_path, truth):
    """1 kHz stamps in epoch seconds are rounded to 2.4e-7 s: their median step is off by that
    much (14 ms over a minute), their mean step is not."""
    rows = {}
    for name, t in (("relative", truth["time"]), ("epoch", 1.7e9 + truth["time"])):
        text = "time,voltage,arm_angle\n" + "\n".join(
            f"{float(a)!r},{float(b)!r},{float(c)!r}"
            for a, b, c in zip(t, truth["voltage"], truth["angle"])
        )
        (tmp_path / f"{name}.csv").write_text(text + "\n")
        rows[name] = read_recording(tmp_path / f"{name}.csv")
    steps = np.diff(1.7e9 + truth["time"])
    assert abs(np.median(steps) - 1 / FS) > 1e-8  # the trap
    # a quantum over the duration
    assert rows["epoch"].dt == pytest.approx(rows["relative"].dt, rel=1e-7)
    assert np.allclose(
        rows["epoch"].time_s - rows["epoch"].time_s[0], rows["relative"].time_s, atol=1e-6
    )


NUMERIC_BODY_CASES = [
    "a,b\n1,2\n\n3,4\n",
    "a,b\n1,2\n,\n3,4\n",  # a line of separators only
    "a;b\n1,5;2\n",  # decimal comma
    "a,b\n1,x\n",  # a text column
    "a,b\n1,2,3\n",  # a line too long
    "a,b\n",
    "1,2\n3,4\n",  # no header
    "a\tb\n1\t2\n",
    "a,b\n 1 , 2 \n",
    "a,b\nnan,inf\n",
    "a,b\n1_0,2\n",
    "a,b\n1,\n",  # an empty cell
    'a,b\n"1",2\n',  # quoted
    "a,b\n1,2\n# a remark, inside\n3,4\n",
    "a,b\n1,2 # trailing\n",
    "a,b\n1,2\x00\n",
]


@pytest.mark.parametrize("text", NUMERIC_BODY_CASES)
def test_the_fast_reader_of_numbers_gives_what_the_general_reader_gives(text, monkeypatch):
    from mechanism.files import formats

    def read():
        try:
            return formats._read_csv(text.encode(), "x.csv")
        except UserError as exc:
            return str(exc)

    fast = read()
    monkeypatch.setattr(formats, "_numeric_body", lambda *args: None)
    general = read()
    if isinstance(general, str):
        assert fast == general
        return
    assert fast[1] == general[1] and list(fast[0]) == list(general[0])
    for name, column in general[0].items():
        assert type(fast[0][name]) is type(column)
        if isinstance(column, list):  # a text column
            assert fast[0][name] == column
        else:
            assert np.array_equal(fast[0][name], column, equal_nan=True)


def test_a_bench_recording_reads_the_same_through_both_readers(tmp_path, monkeypatch):
    import mechanism
    from mechanism.files import formats

    path = tmp_path / "r.csv"
    mechanism.write_bench_recording(
        mechanism.load_machine("sapphire870"), [], 1, path, duration_s=5.0
    )
    fast = formats._read_csv(path.read_bytes(), "r.csv")
    monkeypatch.setattr(formats, "_numeric_body", lambda *args: None)
    general = formats._read_csv(path.read_bytes(), "r.csv")
    assert fast[1] == general[1] and list(fast[0]) == list(general[0])
    assert all(np.array_equal(fast[0][k], general[0][k]) for k in general[0])
