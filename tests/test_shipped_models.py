"""Every shipped machine (menagerie style): its description loads, its self-contained MJCF
and its scene compile and step in stock MuJoCo without a single warning, and the machine
runs forward under a positive voltage (a servo: towards a positive goal)."""

import mujoco
import numpy as np
import pytest

import mechanism
from mechanism.machine.models import ASSETS, shipped_machines, shipped_model, shipped_scene

MACHINES = mechanism.shipped_machines()


def test_the_sewing_machine_is_shipped():
    assert "sapphire870" in MACHINES


def _step_without_warnings(model: mujoco.MjModel, voltage: float, seconds: float) -> mujoco.MjData:
    data = mujoco.MjData(model)
    data.ctrl[:] = voltage
    for _ in range(int(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    warnings = {
        mujoco.mjtWarning(i).name: data.warning[i].number
        for i in range(len(data.warning))
        if data.warning[i].number
    }
    assert not warnings, warnings
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    return data


@pytest.mark.parametrize("name", MACHINES)
def test_self_contained_mjcf_steps_in_stock_mujoco(name, tmp_path):
    machine = mechanism.load_machine(name)
    path = machine.to_xml(tmp_path / f"{name}.xml")
    model = mujoco.MjModel.from_xml_path(str(path))
    shaft = model.joint(machine.shaft_joint)
    if machine.description.drive_tables[machine.motor_joint]["type"] == "servo":
        # a servo's actuator carries its position loop: ctrl is the goal of its joint (rad)
        assert model.nu == 1 and model.actuator_biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE
        start = model.qpos0[shaft.qposadr[0]]
        data = _step_without_warnings(model, 12.0, 1.0)
        # forward towards a positive goal
        assert machine.frame.direction * (data.qpos[shaft.qposadr[0]] - start) > 0
        return
    assert model.nu == 1 and model.actuator_dyntype[0] == mujoco.mjtDyn.mjDYN_DCMOTOR
    data = _step_without_warnings(model, 12.0, 1.0)
    # forward under a positive voltage
    assert machine.frame.direction * data.qvel[shaft.dofadr[0]] > 0


@pytest.mark.parametrize("path", sorted((ASSETS / "mjcf").glob("*.xml")), ids=lambda p: p.name)
def test_every_mjcf_in_assets_loads_and_steps_in_stock_mujoco_where_it_lies(path):
    """The card's ``assets/mjcf/*.xml``: each model and scene, read by MuJoCo itself from its folder."""
    _step_without_warnings(mujoco.MjModel.from_xml_path(str(path)), 0.0, 0.2)


def test_each_shipped_machine_has_its_mjcf_scene_and_provenance_in_assets_mjcf():
    folder = ASSETS / "mjcf"
    expected = {shipped_model(name).name for name in shipped_machines()}
    expected |= {shipped_scene(name).name for name in shipped_machines()} | {
        f"{name}.md" for name in shipped_machines()
    }
    assert {p.name for p in folder.iterdir()} == expected  # one place each, nothing else


@pytest.mark.parametrize("name", MACHINES)
def test_every_machine_has_a_readme_with_its_provenance(name):
    readme = shipped_model(name).with_name(f"{name}.md").read_text()
    assert "mechanism convert" in readme  # how the MJCF was made from its CAD export


@pytest.mark.slow
def test_the_wheel_carries_the_models_and_runs_outside_the_checkout(tmp_path):
    """pip builds the wheel; unpacked away from the checkout, it finds and simulates its machine."""
    import subprocess
    import sys
    import zipfile
    from pathlib import Path

    repo = Path(__file__).resolve().parent.parent
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(repo)],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    wheel = next(tmp_path.glob("mechanism-*.whl"))
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    assert (site / "mechanism" / "assets" / "machines" / "sapphire870.toml").is_file()
    assert (site / "mechanism" / "converters" / "__init__.py").is_file()
    assert not (
        site / "mechanism" / "assets" / "recordings"
    ).exists()  # package data is the listed files only
    code = "import mechanism; m = mechanism.load_machine(); print(m.model_path); print(mechanism.simulate(m, voltage_V=12, duration_s=1, reduced=True).mean_speed_rpm)"
    result = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(site), "HOME": str(tmp_path)},
    )
    assert result.returncode == 0, result.stderr
    path, rpm = result.stdout.split()
    assert Path(path).is_relative_to(site) and 400 < float(rpm) < 700
