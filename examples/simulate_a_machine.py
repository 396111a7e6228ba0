"""Simulate the shipped sewing machine at three voltages and print the steady arm speed."""

import mechanism

machine = mechanism.load_machine()  # or mechanism.load_machine("my_machine.toml")
for volts in (4.48, 12.49, 19.6):
    run = mechanism.simulate(machine, voltage_V=volts, duration_s=3.0)
    print(f"{volts:5.2f} V: {run.mean_speed_rpm:6.1f} rpm")
