"""A small, independent truth model for the diagnosis tests (a stand-in until/besides the
project's virtual test bench, ``mechanism.testbench``).

Deliberately a different code path from ``mechanism.dynamics.lumped`` / ``mechanism.sysid.effects``:
fixed-step explicit Euler at 0.1 ms on the arm side, a slider-crank needle bar with real geometry,
Hess-Soom (not Tustin) Stribeck friction, a thermal state heated by the friction power,
a half-sine needle-penetration pulse, a PWM-switch voltage curve, a two-mass belt, and an
eccentric encoder. Written from the physics, not from the diagnosis formulas, so the tests
are not circular and the diagnosis meets model-form differences like the held-out bench.
"""

from __future__ import annotations

import math

import numpy as np

KT, KE, R, N = 0.017, 0.021, 1.1, 8.0
J_M = 2.78e-5  # motor side total
D_M = 2.2e-5
FC_ARM = 0.18
STEP = 2 * math.pi / 20000


def voltage_profile(rng: np.random.Generator, duration: float, fs: float = 1000.0) -> np.ndarray:
    t = np.arange(int(round(duration * fs))) / fs
    u = np.zeros_like(t)
    now = rng.uniform(0.3, 0.8)
    while now < duration:
        if rng.random() < 0.22:
            level, length = 0.0, rng.uniform(1.0, 2.0)
        else:
            level, length = rng.uniform(4.0, 20.0), rng.uniform(2.0, 5.0)
        u[t >= now] = level
        now += length
    return u


def simulate_truth(
    effects=(), seed=0, duration=60.0, fs=1000.0, sub=10, strength=1.0, smooth_friction=0.0
):
    """``smooth_friction`` > 0: Coulomb friction as Fc tanh(w / smooth_friction) without
    stick-slip (what an ODE-solver truth model often does), else Karnopp stick-slip."""
    rng = np.random.default_rng(seed)
    u_log = voltage_profile(rng, duration, fs)
    n_samples = len(u_log)
    h = 1.0 / fs / sub
    effects = set(effects)
    # parameters of the machine, jittered per seed like a real unit
    jm = J_M * rng.uniform(0.85, 1.15)
    dm = D_M * rng.uniform(0.8, 1.2)
    fc = FC_ARM * rng.uniform(0.85, 1.15)
    # effects
    s = strength
    ripple_amp = 0.006 * s * rng.uniform(0.8, 1.2)  # motor side, Nm
    ripple_phase = rng.uniform(0, 2 * math.pi)
    crank_r, rod_l, bar_mass = 0.016, 0.045, 0.35 * s  # slider-crank needle bar
    pf_amp, pf_phase = 0.09 * s * fc, rng.uniform(0, 2 * math.pi)
    fs_excess, ws = 0.35 * s * fc, 2.0  # Hess-Soom
    heat_drop_visc, heat_drop_coul, heat_tau = 0.5 * s, 0.3 * s, 40.0
    needle_load, needle_start, needle_len = 0.35 * s, math.pi - 0.9, 0.8
    belt_f, belt_zeta, motor_share = 18.0, 0.04, 0.3
    ecc = 0.006 * s
    ecc_phase = rng.uniform(0, 2 * math.pi)
    current_limit = 4.0 / s  # A: about twice the running current, a fifth of the largest step's
    # outside the library too: brushes that take a volt whichever way the current flows; a supply
    # that drops out for 30-60 ms now and then (the log keeps the commanded voltage); an accessory
    # shaft turning 1.6 times per arm turn with an unbalanced part on it
    brush_drop_V = 1.0 * s
    dropouts = []
    if "supply_dropout" in effects:
        now = rng.uniform(1.0, 3.0)
        while now < duration:
            dropouts.append((now, now + rng.uniform(0.03, 0.06)))
            now += rng.uniform(1.5, 4.0)
    accessory_ratio, accessory_Nm = 1.6, 0.12 * s
    accessory_phase = rng.uniform(0, 2 * math.pi)
    # a housing on soft feet that rocks about the arm's axis (9 Hz, 20x the drive's inertia): the
    # drive's torques react on it, and the encoder reads the arm against the rocking housing
    base_inertia = 20.0 * jm * N * N / s
    base_stiffness = base_inertia * (2 * math.pi * 9.0) ** 2
    base_damping = 2 * 0.08 * math.sqrt(base_stiffness * base_inertia)

    def applied_voltage(u):
        if "voltage_nonlinearity" not in effects:
            return u
        x = u / 24.0
        return u * (1 - 0.28 * s * (1 - x) ** 2 + 0.05 * s * math.sin(math.pi * x))

    def crank(theta):
        # needle-bar height and its derivatives for a slider-crank, TDC at theta = 0
        st, ct = math.sin(theta), math.cos(theta)
        root = math.sqrt(rod_l**2 - (crank_r * st) ** 2)
        dx = -crank_r * st - crank_r**2 * st * ct / root
        ddx = (
            -crank_r * ct
            - crank_r**2 * (ct * ct - st * st) / root
            - crank_r**4 * st * st * ct * ct / root**3
        )
        return dx, ddx

    def coulomb(theta, temp):
        f = fc
        if "position_friction" in effects:
            f += pf_amp * math.cos(theta - pf_phase)
        if "needle_penetration" in effects:
            a = (theta - needle_start) % (2 * math.pi)
            if a < needle_len:
                f += needle_load * math.sin(math.pi * a / needle_len)
        if "thermal_drift" in effects:
            f *= 1 - heat_drop_coul * temp
        return f

    def viscous(temp):
        return dm * (1 - heat_drop_visc * temp) if "thermal_drift" in effects else dm

    def friction(theta, w, temp):
        f = coulomb(theta, temp)
        if "stribeck" in effects:
            f += fs_excess / (1 + (w / ws) ** 2)
        return f

    theta = rng.uniform(0, 2 * math.pi)
    w = 0.0  # arm velocity
    wm = 0.0  # motor velocity (arm units) for the belt
    twist = 0.0
    temp = 0.0
    stuck = True
    belt = "belt_compliance" in effects
    j_arm_total = jm * N * N
    out_theta = np.empty(n_samples)
    phi = phid = 0.0  # the rocking housing's angle and speed
    # a pulley loose on the motor's shaft: it grips up to a torque (arm side), beyond which the
    # motor (30 % of the inertia) slips against it until their speeds meet again
    slip_limit = 0.6 / s
    slipping, slip_sign, wm_slip = False, 1.0, 0.0
    dropout_at = np.zeros(n_samples, bool)
    for begin, end in dropouts:
        dropout_at[int(begin * fs) : int(end * fs)] = True
    # a supply that gives no more than 12 V; a driver that applies the command 10 ms late
    supply_max_V = 12.0 / s
    late = int(round(0.010 * s * fs)) if "input_delay" in effects else 0
    for k in range(n_samples):
        out_theta[k] = theta
        u = 0.0 if dropout_at[k] else applied_voltage(u_log[max(k - late, 0)])
        if "supply_limit" in effects:
            u = max(-supply_max_V, min(supply_max_V, u))
        for _ in range(sub):
            motor_speed = wm if belt else (wm_slip if slipping else w)
            current = (u - KE * N * motor_speed) / R
            if "brush_drop" in effects and current != 0.0:
                current = math.copysign(max(abs(current) - brush_drop_V / R, 0.0), current)
            if "current_limit" in effects:  # outside the library: a current-limited driver
                current = max(-current_limit, min(current_limit, current))
            drive_motor = N * KT * current
            if "torque_ripple" in effects:
                drive_motor -= N * ripple_amp * math.sin(N * theta + ripple_phase)
            if "accessory_torque" in effects:
                # virtual work: the accessory's torque acts ratio times on the arm
                drive_motor -= (
                    accessory_ratio
                    * accessory_Nm
                    * math.sin(accessory_ratio * theta + accessory_phase)
                )
            j_lin, grav, quad = 0.0, 0.0, 0.0
            if "linkage_dynamics" in effects:
                dx, ddx = crank(theta)
                j_lin = bar_mass * dx * dx
                grav = bar_mass * 9.81 * dx  # potential energy m g x
                quad = bar_mass * dx * ddx  # 1/2 dJ/dtheta
            visc = viscous(temp) * N * N
            if belt:
                jmot = motor_share * j_arm_total
                jarm = j_arm_total - jmot + j_lin
                k_b = (2 * math.pi * belt_f) ** 2 / (1 / jmot + 1 / (j_arm_total - jmot))
                c_b = 2 * belt_zeta * math.sqrt(k_b * jmot * (j_arm_total - jmot) / j_arm_total)
                fb = k_b * twist + c_b * (wm - w)
                wm += h * (drive_motor - fb) / jmot
                tau = fb - visc * w - grav - quad * w * w
                jeff = jarm
            else:
                tau = drive_motor - visc * w - grav - quad * w * w
                jeff = j_arm_total + j_lin
            if "pulley_slip" in effects:
                jmot = motor_share * j_arm_total
                if not slipping:
                    # the torque through the pulley, were motor and arm one body
                    moving = math.copysign(friction(theta, w, temp), w) if w != 0.0 else 0.0
                    through = drive_motor - jmot * (tau - moving) / jeff
                    if abs(through) > slip_limit:
                        slipping, slip_sign, wm_slip = True, math.copysign(1.0, through), w
                if slipping:
                    wm_slip += h * (drive_motor - slip_sign * slip_limit) / jmot
                    tau = slip_sign * slip_limit - visc * w - grav - quad * w * w
                    jeff = j_arm_total - jmot + j_lin
            fr = friction(theta, w, temp)
            w_before = w
            if smooth_friction > 0:
                w += h * (tau - fr * math.tanh(w / smooth_friction)) / jeff
            elif stuck:
                if abs(tau) > fr:
                    stuck = False
                    w = h * (tau - math.copysign(fr, tau)) / jeff
            else:
                # RK-free midpoint on the smooth part; friction by the sign of w
                a1 = (tau - math.copysign(fr, w)) / jeff
                w_new = w + h * a1
                if w_new * w < 0 or w_new == 0:
                    w_new, stuck = 0.0, True
                w = w_new
            if "base_rocking" in effects:
                # the drive's internal torque reacts on the housing; in the housing's frame the arm
                # feels the housing's angular acceleration as a torque of inertia
                internal = jeff * (w - w_before) / h
                phidd = (-base_stiffness * phi - base_damping * phid - internal) / base_inertia
                phid += h * phidd
                phi += h * phid
                # a stuck arm rides with the housing until that torque passes its friction
                if not stuck or abs(jeff * phidd) > fr:
                    w -= h * phidd
                    stuck = False
            if slipping and (wm_slip - w) * slip_sign <= 0.0:
                slipping = False  # the speeds met: it grips again
            theta += h * w
            if belt:
                twist += h * (wm - w)
            if "thermal_drift" in effects:
                power = abs(w) * fr + visc * w * w
                temp += h * (power / 30.0 - temp) / heat_tau  # warms towards P/30 W with a 40 s lag
                temp = min(temp, 1.0)
    angle = out_theta.copy()
    if "encoder_eccentricity" in effects:
        angle = angle + ecc * np.cos(angle - ecc_phase)
    angle = np.floor(angle / STEP) * STEP + rng.normal(0, 0.3 * STEP, n_samples)
    t = np.arange(n_samples) / fs
    truth = {
        "inertia_motor_side_kgm2": jm,
        "viscous_motor_side_Nm_s_per_rad": dm,
        "coulomb_arm_Nm": fc,
    }
    return t, u_log, angle, truth


def write_csv(
    path, t, u, angle, extra_comment="synthetic truth (tests/helpers/synthetic_truth.py)"
):
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"# {extra_comment}\n")
        f.write("time,voltage,arm_angle\n")
        for row in zip(t, u, angle):
            f.write("%.6f,%.4f,%.7f\n" % row)
    return path
