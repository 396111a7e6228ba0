#!/bin/sh
# Regenerates the shipped virtual-bench recordings (CSV + truth JSON) in this folder.
# Deterministic per seed; tests/test_testbench.py checks the files match what this writes.
set -e
cd "$(dirname "$0")"
MECHANISM="${MECHANISM:-mechanism}"
$MECHANISM testbench --effect none --seed 1 -o clean_seed1.csv
$MECHANISM testbench --effect torque_ripple --seed 3 -o torque_ripple_seed3.csv
$MECHANISM testbench --effect position_friction --seed 3 -o position_friction_seed3.csv
