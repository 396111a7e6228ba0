"""Machine words come from the machine: the effect library offers fabric penetration only where a
tool works in fabric, and the reports fold the motor angle at the machine's own ratio."""

import pytest


@pytest.mark.slow
def test_the_press_is_offered_no_fabric_penetration_and_folds_at_its_ratio():
    import mechanism
    from mechanism.errors import UserError
    from mechanism.sysid.effects import library
    from mechanism.sysid.nominal import machine_drive_nominal

    press = machine_drive_nominal(mechanism.load_machine("press"))
    assert press.ratio == pytest.approx(20.0)
    assert not press.tool_in_fabric and "RAM-1" in press.zero_meaning
    assert "needle_penetration" not in library(press)
    with pytest.raises(UserError, match="no tool working in fabric"):
        library(press, ["needle_penetration"])
    sewing = machine_drive_nominal(mechanism.load_machine("sapphire870"))
    assert sewing.tool_in_fabric and "needle_penetration" in library(sewing)


@pytest.mark.slow
def test_report_traces_carry_the_machines_ratio_and_zero():
    import numpy as np

    from mechanism.sysid.report import Traces, _plots

    t = np.linspace(0, 1, 2000)
    traces = Traces(
        t,
        10 * t,
        np.full_like(t, 12.0),
        np.full_like(t, 10.0),
        {"model": np.full_like(t, 10.0)},
        ratio=20.0,
        zero_meaning="RAM-1 at its top",
    )
    import matplotlib

    matplotlib.use("Agg")
    from mechanism.files.plotting import plt

    labels = []
    original = plt.Axes.set

    def spy(self, **kwargs):
        labels.append(kwargs.get("xlabel", ""))
        return original(self, **kwargs)

    plt.Axes.set = spy
    try:
        import tempfile
        from pathlib import Path

        import warnings

        with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
            # a residual of zero (an exact fit) plots without matplotlib's complaints
            warnings.simplefilter("error")
            _plots(traces, Path(folder))
    finally:
        plt.Axes.set = original
    assert "motor angle [deg] (20 per shaft revolution)" in labels
    assert "shaft angle [deg] (0 = RAM-1 at its top)" in labels
