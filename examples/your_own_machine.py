"""From a CAD export to a diagnosed recording, in Python, with a hand-written description.

Run from the repository root: python examples/your_own_machine.py
"""

import tempfile
from pathlib import Path

import mechanism

export = mechanism.shipped_export("sapphire870")  # or the path of your own export
work = Path(tempfile.mkdtemp())
(work / "machine.toml").write_text(f"""
[machine]
name = "my_machine"
model = "{export}"   # a CAD export: converted on first use and cached

[drive]
motor_joint = "motor"
shaft_joint = "arm_shaft"
zero_site = "needle_tip"

[motor]
type = "dc"
resistance_ohm = 1.1
torque_constant_Nm_per_A = 0.017
back_emf_V_s_per_rad = 0.021

[friction."arm_shaft"]
coulomb_Nm = 0.18

[tool]
site = "needle_tip"
plate = "needle_plate"
""")
machine = mechanism.load_machine(work / "machine.toml")
print("stroke", round(mechanism.tool_motion(machine).stroke_mm, 3), "mm")
print(
    "speed at 12 V",
    round(mechanism.simulate(machine, voltage_V=12, duration_s=2).mean_speed_rpm),
    "rpm",
)
truth = mechanism.write_bench_recording(machine, ["torque_ripple"], seed=3, path=work / "bench.csv")
found = mechanism.diagnose(machine, work / "bench.csv").to_json()["effects"]
print("found", [e["name"] for e in found], "- the truth is in", truth)
