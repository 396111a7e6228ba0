"""Design variants: what each parameter changes, variant files, batch checks in parallel."""

import json

import mujoco
import numpy as np
import pytest

from tests.helpers import mechanisms as M
from mechanism.inspection.clearance import Pair
from mechanism.errors import UserError
from mechanism.kinematics.pose import solve_pose, sweep
from mechanism.inspection.variants import apply_parameter, parameter, read_variants, run_variants


@pytest.fixture(scope="module")
def nominal():
    return M.needle_and_plate().compile()


def _edited(nominal, target, value):
    model = M.needle_and_plate().compile()
    apply_parameter(model, nominal, parameter("p", target), value)
    return model


def test_coupling_offset_advances_the_hook(nominal):
    model = _edited(nominal, "coupling:hook_drive:hook_deg", 30.0)
    for m, shift in ((nominal, 0.0), (model, 30.0)):
        data = mujoco.MjData(m)
        solve_pose(m, data, {"arm_shaft": 0.7})
        hook = data.qpos[m.joint("hook").qposadr[0]]
        expected = 2 * 0.7 + np.radians(90 - 2 * M.HOOK_PASS_DEG + shift)
        assert hook == pytest.approx(expected, abs=1e-9)
    # the same timing change expressed on the arm side of the coupling: advance the arm by -15 deg
    arm_side = _edited(nominal, "coupling:hook_drive:arm_shaft_deg", -15.0)
    data = mujoco.MjData(arm_side)
    solve_pose(arm_side, data, {"arm_shaft": 0.7})
    assert data.qpos[arm_side.joint("hook").qposadr[0]] == pytest.approx(
        2 * 0.7 + np.radians(90 - 2 * M.HOOK_PASS_DEG + 30), abs=1e-9
    )


def test_crank_radius_changes_the_stroke(nominal):
    model = _edited(nominal, "joint:crank_pin:radial_mm", 1.0)
    angles = np.linspace(0, 2 * np.pi, 361)
    tip = []
    data = mujoco.MjData(model)
    for pose in sweep(model, angles, "arm_shaft", data=data):
        data.qpos[:] = pose
        mujoco.mj_kinematics(model, data)
        tip.append(data.site("needle_tip").xpos[2])
    assert max(tip) - min(tip) == pytest.approx(2 * (M.R + 0.001), abs=1e-7)


def test_part_offset_moves_the_part_and_its_named_frames(nominal):
    model = _edited(nominal, "part:needle:z_mm", 0.5)
    data0, data1 = mujoco.MjData(nominal), mujoco.MjData(model)
    for m, d in ((nominal, data0), (model, data1)):
        solve_pose(m, d, {"arm_shaft": 2.0})
    assert data1.site("needle_tip").xpos[2] - data0.site("needle_tip").xpos[2] == pytest.approx(
        0.0005, abs=1e-9
    )
    assert data1.geom("needle").xpos[2] - data0.geom("needle").xpos[2] == pytest.approx(
        0.0005, abs=1e-9
    )
    np.testing.assert_allclose(
        data1.site("needle_bar").xpos, data0.site("needle_bar").xpos, atol=1e-12
    )


def test_joined_targets_move_together(nominal):
    """needle-bar height: the bar and the needle (with its named frames) move as one."""
    model = _edited(nominal, "part:needle_bar:z_mm+part:needle:z_mm", -0.3)
    for name in ("needle_tip", "needle", "needle_bar"):
        assert model.site(name).pos[2] - nominal.site(name).pos[2] == pytest.approx(
            -0.0003, abs=1e-12
        )


def test_unknown_targets_list_close_matches(nominal):
    with pytest.raises(UserError, match="close matches: hook_drive"):
        parameter("p", "coupling:hook_drv:hook_deg").check(nominal)
    with pytest.raises(UserError, match="joins hook and arm_shaft"):
        parameter("p", "coupling:hook_drive:needle_bar_deg").check(nominal)
    with pytest.raises(UserError, match="close matches: crank_pin"):
        parameter("p", "joint:crank_pn:radial_mm").check(nominal)
    with pytest.raises(UserError, match="expected coupling"):
        parameter("p", "wobble")


def _write(tmp_path, name, content):
    path = tmp_path / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return path


def test_json_rows_nominal_explicit_grid_times_samples(tmp_path):
    doc = {
        "format": "mechanism-variants/1",
        "parameters": {"timing": "coupling:hook_drive:hook_deg", "height": "part:needle:z_mm"},
        "variants": [{"name": "late hook", "timing": -30}],
        "sweep": {"timing": {"start": -2, "stop": 2, "num": 3}},
        "samples": {
            "count": 200,
            "seed": 7,
            "tolerances": {"height": {"dist": "normal", "std": 0.05}},
        },
    }
    variants = read_variants(_write(tmp_path, "v.json", doc))
    assert [p.name for p in variants.parameters] == ["timing", "height"]
    assert variants.names[:2] == ["nominal", "late hook"] and len(variants) == 2 + 3 * 200
    np.testing.assert_array_equal(variants.values[0], [0, 0])
    assert sorted(set(variants.values[2:, 0])) == [-2.0, 0.0, 2.0]
    heights = variants.values[2:202, 1]
    assert abs(heights.mean()) < 0.02 and heights.std() == pytest.approx(0.05, rel=0.2)
    again = read_variants(_write(tmp_path, "w.json", doc))
    np.testing.assert_array_equal(again.values, variants.values)  # the seed makes it reproducible


def test_csv_variants_with_names(tmp_path):
    path = _write(tmp_path, "v.csv", "name,coupling:hook_drive:hook_deg\nearly,10\nlate,-30\n")
    variants = read_variants(path)
    assert variants.names == ["nominal", "early", "late"]
    np.testing.assert_array_equal(variants.values[:, 0], [0, 10, -30])


@pytest.mark.parametrize(
    "content, message",
    [
        ("{not json", "not valid JSON"),
        (
            {"format": "mechanism-variants/1", "sweep": {"hook_timing_deg": [1]}, "colour": 1},
            "unknown key",
        ),
        ({"parameters": {"t": "coupling:hook_drive:hook_deg"}, "sweep": {"t": []}}, "empty list"),
        (
            {
                "parameters": {"t": "coupling:hook_drive:hook_deg"},
                "samples": {"count": 3, "tolerances": {"t": {"dist": "cauchy"}}},
            },
            "normal",
        ),
        (
            {"parameters": {"t": "coupling:hook_drive:hook_deg"}, "variants": [{"t": "late"}]},
            "finite number",
        ),
        ({"parameters": {"t": "twist:hook:deg"}}, "expected coupling"),
        ("coupling:hook_drive:hook_deg\n1\nabc\n", "not a number"),
    ],
)
def test_malformed_variant_files(tmp_path, content, message):
    suffix = ".csv" if isinstance(content, str) and not content.startswith("{") else ".json"
    with pytest.raises(UserError, match=message):
        read_variants(_write(tmp_path, "bad" + suffix, content))


@pytest.mark.slow
def test_batch_in_parallel_flags_the_mistimed_hook(tmp_path, nominal, capsys):
    doc = {
        "parameters": {"timing": "coupling:hook_drive:hook_deg"},
        "variants": [{"name": "late hook", "timing": -30}],
        "sweep": {"timing": [-4, 4]},
    }
    variants = read_variants(_write(tmp_path, "v.json", doc))
    pairs = [Pair("needle", "hook")]
    parallel = run_variants(
        nominal, variants, pairs, required_mm=0.05, driver="arm_shaft", workers=2
    )
    assert "variants" in capsys.readouterr().err  # the progress bar
    rows = {row["variant"]: row for row in parallel.table()}
    assert rows["nominal"]["pass"] == 1
    assert rows["nominal"]["needle_vs_hook_min_mm"] == pytest.approx(M.HOOK_GAP * 1e3, abs=0.01)
    assert rows["late hook"]["pass"] == 0 and rows["late hook"]["needle_vs_hook_min_mm"] < 0
    # a timing error moves the pass angle by half of it (the hook turns at twice the arm speed)
    assert rows["grid 2"]["needle_vs_hook_angle_deg"] == pytest.approx(M.HOOK_PASS_DEG - 2, abs=0.1)
    serial = run_variants(
        nominal, variants, pairs, required_mm=0.05, driver="arm_shaft", workers=1, progress=False
    )
    assert [r["needle_vs_hook_min_mm"] for r in serial.rows] == pytest.approx(
        [r["needle_vs_hook_min_mm"] for r in parallel.rows], abs=1e-9
    )


def _rows_on_a_local_ray_instance(variants_path):
    """In a process of its own: a local Ray instance leaves state in the process that started it
    (its node address, its session), which a later test's driver of a `ray start` cluster would meet."""
    import ray

    batch = run_variants(
        M.needle_and_plate().compile(),
        read_variants(variants_path),
        [Pair("needle", "hook")],
        driver="arm_shaft",
        workers=2,
        backend="ray",
        progress=False,
    )
    return [row["pass"] for row in batch.rows], ray.is_initialized()


@pytest.mark.slow
@pytest.mark.xdist_group("ray")
def test_ray_backend(tmp_path):
    import multiprocessing

    pytest.importorskip(
        "ray", reason="Ray is not installed (optional: pip install 'mechanism[ray]')"
    )
    variants = _write(
        tmp_path,
        "v.json",
        {"parameters": {"t": "coupling:hook_drive:hook_deg"}, "sweep": {"t": [-30, 0]}},
    )
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        passes, still_initialized = pool.apply(_rows_on_a_local_ray_instance, (variants,))
    assert passes == [1, 0, 1]
    assert not still_initialized  # the local instance it started is shut down
