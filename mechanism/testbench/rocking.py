"""The bench for a drive that rocks: a shaft that moves between two hard stops (a rocker, a
servo arm) instead of turning whole revolutions.

Voltage plateaus of one sign would run such a shaft into a stop within a fraction of a
second, so the bench moves it the way a test rig does: point to point inside its travel.
Each move picks a target in the middle of the travel (:data:`SAFE_MARGIN` of it clear of
each stop) and a crossing speed, applies the voltage the described drive needs for that
speed (its datasheet, friction scale and reflected damping) with the sign towards the
target, raises it by steps while the shaft does not break away, and drops to 0 V when the shaft
passes the target; a rest of 0.2-1.2 s follows. A bench controller checks the shaft every
:data:`CONTROL_PERIOD_S`. The logged voltage is what it commanded, so the recording keeps the
bench CSV contract and every reader takes it.

The truth model is the bench's own integrator (:mod:`mechanism.testbench.simulate`) with the
machine's linkage table over the travel (its angle-dependent inertia and gravity torque from
the CAD model) and inelastic stops at the ends of the travel.
"""

from __future__ import annotations

import math

import numpy as np

from mechanism.errors import UserError

CONTROL_PERIOD_S = 0.01  # the bench's position check (100 Hz)
SAFE_MARGIN = 0.15  # targets stay this share of the travel clear of each stop
MIN_MOVE = 0.25  # a move covers at least this share of the safe band
# a move crosses the safe band in this time at its target speed (log-uniform)
CROSSING_S = (0.6, 4.0)
REST_S = (0.2, 1.2)  # the rest at 0 V after each move
# a shaft slower than a tenth of its target speed this long after a move starts ...
BREAKAWAY_WAIT_S = 0.3
# ... gets 15 % more voltage, again after as long (up to the supply): few voltage steps
BREAKAWAY_STEP = 1.15
VOLTAGE_RESOLUTION_V = 0.01

# Effects whose physics needs a shaft or motor that turns whole revolutions (or the sewing
# machine's needle and slider-crank): a rocking drive refuses them, with the reason.
NEEDS_TURNING = {
    "needle_penetration": "it is a sewing needle piercing fabric once per revolution",
    "linkage_dynamics": "it is the sewing machine's slider-crank needle bar (a rocking machine's own linkage is in its truth model already)",
}
NEEDS_MOTOR_TURNS = {
    "torque_ripple": "its ripple is periodic in the motor angle, and the motor turns less than one revolution over the travel",
    "encoder_eccentricity": "its error is periodic over a shaft revolution, and the shaft turns less than one",
}


def refuse_effects(names, nominal) -> None:
    """UserError naming the first effect that makes no sense on this rocking drive."""
    from mechanism.testbench.truth import PWM_ANCHORS_V

    lo, hi = nominal.travel_rad
    motor_span = abs(nominal.ratio) * (hi - lo)
    low, top = working_voltages(nominal)
    for name in names:
        why = NEEDS_TURNING.get(name)
        if (
            why is None
            and name in NEEDS_MOTOR_TURNS
            and (name == "encoder_eccentricity" or motor_span < 2 * math.pi)
        ):
            why = NEEDS_MOTOR_TURNS[name]
        if name == "voltage_nonlinearity" and top < PWM_ANCHORS_V[0]:
            why = (
                f"its switch distortion is anchored at {PWM_ANCHORS_V[0]:g} and {PWM_ANCHORS_V[1]:g} V, and the bench "
                f"moves this drive with {low:.2g}-{top:.2g} V, where the extrapolated loss would swallow most of the voltage"
            )
        if why:
            raise UserError(
                f"effect {name} does not apply to a shaft that rocks between "
                f"{math.degrees(lo):.4g} and {math.degrees(hi):.4g} deg: {why}"
            )


def linkage_table(nominal) -> tuple[float, float, np.ndarray] | None:
    """(first angle, last angle, rows of J - mean J, J'/2, G) on a uniform grid of shaft angles,
    from the machine's linkage tables over the travel; None without tables."""
    tables = getattr(nominal, "linkage", None)
    if tables is None:
        return None
    angle = np.asarray(tables.angle_rad, dtype=float)
    rows = np.column_stack(
        [
            tables.inertia_variation_kgm2,
            0.5 * np.asarray(tables.dinertia_drad),
            tables.gravity_torque_Nm,
        ]
    )
    grid = np.linspace(angle[0], angle[-1], len(angle))
    if not np.allclose(grid, angle, rtol=0, atol=1e-12 * max(1.0, abs(angle[-1]))):
        rows = np.column_stack([np.interp(grid, angle, rows[:, j]) for j in range(3)])
    return float(grid[0]), float(grid[-1]), np.ascontiguousarray(rows)


def start_angle(nominal, rng) -> float:
    lo, hi = safe_band(nominal)
    return float(rng.uniform(lo, hi))


def safe_band(nominal) -> tuple[float, float]:
    lo, hi = nominal.travel_rad
    margin = SAFE_MARGIN * (hi - lo)
    return lo + margin, hi - margin


def working_voltages(nominal) -> tuple[float, float]:
    """The bench's move voltages for the described drive: slowest and fastest crossing [V]."""
    lo, hi = safe_band(nominal)
    slowest, fastest = (
        voltage_for_speed(nominal, (hi - lo) / crossing)
        for crossing in sorted(CROSSING_S, reverse=True)
    )
    return slowest, fastest


def voltage_for_speed(nominal, speed: float) -> float:
    """The described drive's steady voltage for ``speed`` [rad/s, shaft] against its friction scale."""
    m, n = nominal.motor, nominal.ratio
    damping = (
        m.torque_constant_Nm_per_A * m.back_emf_V_s_per_rad * n * n / m.resistance_ohm
        + nominal.viscous_motor_side * n * n
    )
    return (
        m.resistance_ohm
        / (m.torque_constant_Nm_per_A * n)
        * (nominal.torque_scale_Nm + speed * damping)
    )


def run(step, n: int, rate: float, state: dict, rng, nominal, supply_V: float):
    """Move the shaft point to point for ``n`` samples. ``step(logged_voltage, state, end)``
    integrates the truth over a chunk of logged voltage from ``state`` and fills ``end``;
    returns (logged voltage per sample, trace chunks, the moves made)."""
    period = max(1, int(round(CONTROL_PERIOD_S * rate)))
    lo, hi = safe_band(nominal)
    span = hi - lo
    if not span > 0:
        raise UserError("the shaft's travel is empty: it cannot rock")
    logged = np.zeros(n)
    chunks: list[dict] = []
    moves: list[dict] = []
    mode, rest_until = "rest", float(rng.uniform(*REST_S))
    target = volts = speed = 0.0
    direction, move_start = 1.0, 0.0
    current = dict(state)
    for k0 in range(0, n, period):
        k1 = min(n, k0 + period)
        t = k0 / rate
        theta, omega = current["theta_arm"], current["omega_arm"]
        if mode == "move" and direction * (target - theta) <= 0.0:
            mode, volts, rest_until = "rest", 0.0, t + float(rng.uniform(*REST_S))
        elif mode == "move" and t - move_start > BREAKAWAY_WAIT_S and abs(omega) < 0.1 * speed:
            volts = direction * min(abs(volts) * BREAKAWAY_STEP, supply_V)
            move_start = t
        if mode == "rest" and (t >= rest_until or not lo <= theta <= hi):
            for _ in range(100):
                target = float(rng.uniform(lo, hi))
                if abs(target - theta) >= MIN_MOVE * span:
                    break
            direction = 1.0 if target > theta else -1.0
            speed = span / math.exp(rng.uniform(*np.log(CROSSING_S)))
            volts = direction * min(voltage_for_speed(nominal, speed), supply_V)
            mode, move_start = "move", t
            moves.append(
                {"time_s": t, "from_rad": theta, "target_rad": target, "speed_rad_s": speed}
            )
        volts = round(volts / VOLTAGE_RESOLUTION_V) * VOLTAGE_RESOLUTION_V
        logged[k0:k1] = volts
        end: dict = {}
        chunks.append(step(logged[k0:k1], current, end))
        current = end
    return logged, chunks, moves
