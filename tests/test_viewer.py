"""The headless meshcat viewer: a self-contained HTML animation, checked in a real browser."""

import shutil
import subprocess
import tempfile

import mujoco
import numpy as np
import pytest

from tests.helpers import mechanisms as M
from mechanism.inspection.viewer import _color, cycle_motion, recording_motion, view

CHROMIUM_CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def _chromium() -> str:
    for name in CHROMIUM_CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    pytest.skip(
        "no headless Chromium installed (Debian: apt-get install -y chromium); the browser test needs one with SwiftShader WebGL"
    )


def _headless(chromium: str, *args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory() as profile:
        command = [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={profile}",
            "--use-gl=angle",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--window-size=800,600",
            "--virtual-time-budget=8000",
            *args,
        ]
        return subprocess.run(command, capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("viewer") / "needle.xml"
    path.write_text(M.needle_and_plate().to_xml())
    return path


def test_html_is_self_contained(model_file, tmp_path):
    html = tmp_path / "machine.html"
    summary = view(
        html,
        model_file,
        frames=12,
        probe_names=["needle_tip"],
        pairs="needle:hook",
        driver="arm_shaft",
    )
    text = html.read_text()
    assert summary["frames"] == 12
    assert (
        "MeshCat.Viewer" in text
        and "<script src" not in text
        and "http://" not in text.split("<script>")[0]
    )
    assert "needle:hook: min 0.100 mm at 195.0 deg" in text


def test_the_same_scene_writes_the_same_bytes(model_file, tmp_path):
    """meshcat names scene elements by the clock (uuid1): the viewer counts them instead, so
    that two runs on the same inputs write the same file (diffable, and a mix of two is seen)."""
    first, second = tmp_path / "first.html", tmp_path / "second.html"
    for html in (first, second):
        view(html, model_file, frames=4, probe_names=["needle_tip"], driver="arm_shaft")
    assert first.read_bytes() == second.read_bytes()


@pytest.mark.slow
def test_html_renders_in_headless_chromium_with_the_requested_frames(model_file, tmp_path):
    chromium = _chromium()
    html = tmp_path / "machine.html"
    view(html, model_file, frames=37, probe_names=["needle_tip"], driver="arm_shaft")
    dom = _headless(chromium, "--dump-dom", html.as_uri())
    assert 'data-ready="true"' in dom.stdout, dom.stderr[-2000:]
    assert 'data-frames="37"' in dom.stdout
    shot = tmp_path / "shot.png"
    _headless(chromium, f"--screenshot={shot}", html.as_uri())
    from PIL import Image

    pixels = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    # meshcat's background is a vertical gradient: every row is one colour. Rows that vary
    # across the middle of the picture show the model drawn by WebGL.
    middle = pixels[60:520, 150:650]
    varying_rows = int((middle.std(axis=1).max(axis=1) > 10).sum())
    assert varying_rows > 50, f"only {varying_rows} rows show anything but the background"


def test_recording_replays_the_arm_angle(model_file, tmp_path):
    recording = tmp_path / "run.csv"
    time = np.linspace(0, 2, 201)
    angle = 3.0 * time**2  # accelerating from rest, unwrapped past one turn
    rows = "\n".join(f"{t:.6f},12.0,{a:.9f}" for t, a in zip(time, angle))
    recording.write_text("time,voltage,arm_angle\n" + rows + "\n")
    model = mujoco.MjModel.from_xml_path(str(model_file))
    motion = recording_motion(model, recording, frames=9, driver="arm_shaft")
    np.testing.assert_allclose(motion.time_s, np.linspace(0, 2, 9))
    np.testing.assert_allclose(
        motion.qpos[:, model.joint("arm_shaft").qposadr[0]],
        3.0 * np.linspace(0, 2, 9) ** 2,
        atol=1e-9,
    )
    tip = []
    data = mujoco.MjData(model)
    for qpos in motion.qpos:  # same branch as the analytic needle all along
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        tip.append(data.site("needle_tip").xpos[2])
    np.testing.assert_allclose(tip, M.needle_tip_z(3.0 * np.linspace(0, 2, 9) ** 2), atol=1e-8)


def test_cycle_and_colours(model_file):
    model = mujoco.MjModel.from_xml_path(str(model_file))
    motion = cycle_motion(model, frames=5, driver="arm_shaft")
    np.testing.assert_allclose(
        motion.qpos[:, model.joint("arm_shaft").qposadr[0]], np.linspace(0, 2 * np.pi, 5), atol=1e-9
    )
    model.geom_rgba[0] = [1.0, 0.5, 0.0, 0.25]
    assert _color(model, 0) == (0xFF8000, 0.25)


@pytest.mark.slow
def test_serve_starts_a_local_meshcat_server(model_file):
    import urllib.request

    summary = view(None, model_file, frames=4, serve=True, driver="arm_shaft")
    assert summary["url"].startswith("http://127.0.0.1:")
    assert b"meshcat" in urllib.request.urlopen(summary["url"], timeout=10).read().lower()
