// Stepper-motor actuators (PM25S-048 of the Sapphire 870): MuJoCo user callbacks.
//
// An actuator is ours when actuator_user[0] holds STEPPER_MARKER; the layout of the user
// array is written by mechanism/steppers/_drive.py (USER_* indices there, mirrored below). Any
// other actuator is passed to the callback that was installed before ours (or left at
// MuJoCo's defaults: act_dot = 0, bias = 0), because MuJoCo callbacks are process-global.
//
// Circuit model (dyntype user, actdim 4, act = [i_a, i_b, chopper_a, chopper_b]):
//   L di/dt = v - R i - e,  e_a = -p psi sin(p th) w,  e_b = -p psi sin(p th - pi/2) w
//   T = -p psi (i_a sin(p th) + i_b sin(p th - pi/2)) - Tdm sin(4 p th)
// with a fixed-frequency peak-current chopper per phase: the bridge switches on at each
// oscillator tick and off when the current reaches its reference; the off phase is slow
// decay (winding shorted), or fast decay (bridge reversed, diodes conduct until i = 0)
// when the current must fall. The on/off state lives in act so that it is part of the
// simulation state: act_dot = (new - old) / h makes MuJoCo's Euler update land exactly on
// the new value (the model builder uses the Euler integrator for this reason).
//
// Physical model (Righettini et al., thesis eq. 21/25; dyntype none):
//   T = Kt i sin(pi / (2 alpha_p) (alpha_0 - alpha_m)),  i = max(0, (Vs - Kw |w|) / R)

#include <math.h>
#include <mujoco/mujoco.h>

#define STEPPER_MARKER 870048.0
#define KIND_CIRCUIT 1
#define KIND_PHYSICAL 2

enum {
  USER_MARKER = 0, USER_KIND, USER_POLE_PAIRS, USER_DIVISIONS, USER_SINE, USER_CURRENT,
  USER_RESISTANCE, USER_INDUCTANCE, USER_FLUX, USER_DETENT, USER_SUPPLY, USER_CHOP_HZ,
  USER_DECAY_MARGIN, USER_KT, USER_KW, USER_SIZE
};

static mjfAct next_dyn = 0;
static mjfAct next_bias = 0;

void stepper_set_next(mjfAct dyn, mjfAct bias) {
  next_dyn = dyn;
  next_bias = bias;
}

static const mjtNum* stepper_params(const mjModel* m, int id) {
  if (m->nuser_actuator < USER_SIZE) return 0;
  const mjtNum* u = m->actuator_user + (size_t)id * m->nuser_actuator;
  return u[USER_MARKER] == STEPPER_MARKER ? u : 0;
}

static mjtNum sgn(mjtNum x) { return (x > 0) - (x < 0); }

// The driver: quantise the commanded shaft angle to the mode's resolution and give the
// phase current references (full/half step: +-I or 0 per phase; microstepping: I cos, I sin).
static void drive(const mjtNum* u, mjtNum command, mjtNum* ref_a, mjtNum* ref_b, mjtNum* phi_q) {
  mjtNum p = u[USER_POLE_PAIRS], n = u[USER_DIVISIONS], current = u[USER_CURRENT];
  int sine = u[USER_SINE] != 0;
  mjtNum pitch = 0.5 * mjPI / n;                          // electrical angle per (micro)step
  mjtNum offset = (!sine && n == 1) ? 0.25 * mjPI : 0.0;  // full step: both phases on
  mjtNum phi = offset + floor((p * command - offset) / pitch + 0.5) * pitch;
  mjtNum c = cos(phi), s = sin(phi);
  if (sine) {
    *ref_a = current * c;
    *ref_b = current * s;
  } else {
    *ref_a = fabs(c) < 1e-6 ? 0.0 : current * sgn(c);
    *ref_b = fabs(s) < 1e-6 ? 0.0 : current * sgn(s);
  }
  *phi_q = phi;
}

static mjtNum command_of(const mjModel* m, const mjData* d, int id) {
  return d->ctrl[m->actuator_ctrladr[id]];
}

// One phase of the bipolar chopper: returns di/dt and updates the on/off state.
static mjtNum chopper_phase(const mjtNum* u, mjtNum i, mjtNum ref, mjtNum emf, int tick,
                            mjtNum h, mjtNum* on) {
  mjtNum supply = u[USER_SUPPLY], r = u[USER_RESISTANCE], l = u[USER_INDUCTANCE];
  mjtNum margin = u[USER_DECAY_MARGIN] * u[USER_CURRENT];
  int reached = ref != 0 && i * sgn(ref) >= fabs(ref);
  if (ref == 0) {
    *on = 0;
  } else if (tick) {
    *on = !reached;
  } else if (*on && reached) {
    *on = 0;
  }
  if (*on) return (supply * sgn(ref) - r * i - emf) / l;
  int must_fall = i != 0 && (ref == 0 || i * ref < 0 || fabs(i) > fabs(ref) + margin);
  if (!must_fall) {
    if (ref == 0) return 0.0;  // bridge open, no current path
    return (-r * i - emf) / l;  // slow decay: winding shorted by the low side
  }
  mjtNum di = (-supply * sgn(i) - r * i - emf) / l;  // fast decay through the diodes
  if ((i + h * di) * i < 0) di = -i / h;             // diodes stop conducting at zero
  return di;
}

static void circuit_dyn(const mjModel* m, const mjData* d, int id, const mjtNum* u) {
  int out = m->actuator_outadr[id];
  int adr = m->actuator_actadr[id];
  mjtNum theta = d->actuator_length[out], omega = d->actuator_velocity[out];
  mjtNum p = u[USER_POLE_PAIRS], psi = u[USER_FLUX], h = m->opt.timestep, t = d->time;
  mjtNum f = u[USER_CHOP_HZ];
  int tick = floor(t * f + 1e-6) != floor((t - h) * f + 1e-6);
  mjtNum ref_a, ref_b, phi;
  drive(u, command_of(m, d, id), &ref_a, &ref_b, &phi);
  mjtNum emf_a = -p * psi * sin(p * theta) * omega;
  mjtNum emf_b = -p * psi * sin(p * theta - 0.5 * mjPI) * omega;
  mjtNum* act = d->act + adr;
  mjtNum* act_dot = d->act_dot + adr;
  mjtNum on_a = act[2] > 0.5, on_b = act[3] > 0.5;
  act_dot[0] = chopper_phase(u, act[0], ref_a, emf_a, tick, h, &on_a);
  act_dot[1] = chopper_phase(u, act[1], ref_b, emf_b, tick, h, &on_b);
  act_dot[2] = (on_a - act[2]) / h;
  act_dot[3] = (on_b - act[3]) / h;
}

static mjtNum circuit_torque(const mjModel* m, const mjData* d, int id, const mjtNum* u) {
  mjtNum theta = d->actuator_length[m->actuator_outadr[id]];
  const mjtNum* act = d->act + m->actuator_actadr[id];
  mjtNum p = u[USER_POLE_PAIRS], psi = u[USER_FLUX];
  return -p * psi * (act[0] * sin(p * theta) + act[1] * sin(p * theta - 0.5 * mjPI))
         - u[USER_DETENT] * sin(4 * p * theta);
}

static mjtNum physical_torque(const mjModel* m, const mjData* d, int id, const mjtNum* u) {
  int out = m->actuator_outadr[id];
  mjtNum theta = d->actuator_length[out], omega = d->actuator_velocity[out];
  mjtNum p = u[USER_POLE_PAIRS], ref_a, ref_b, phi;
  drive(u, command_of(m, d, id), &ref_a, &ref_b, &phi);
  // the equivalent spring scales with the driver's current vector (two phases on = 1)
  mjtNum magnitude = sqrt(ref_a * ref_a + ref_b * ref_b) / (sqrt(2.0) * u[USER_CURRENT]);
  mjtNum current = (u[USER_SUPPLY] - u[USER_KW] * fabs(omega)) / u[USER_RESISTANCE];
  if (current < 0) current = 0;
  return u[USER_KT] * current * magnitude * sin(phi - p * theta);
}

mjtNum stepper_act_dyn(const mjModel* m, const mjData* d, int id) {
  const mjtNum* u = stepper_params(m, id);
  if (!u) return next_dyn ? next_dyn(m, d, id) : 0;
  if (u[USER_KIND] == KIND_CIRCUIT && m->actuator_actnum[id] == 4) circuit_dyn(m, d, id, u);
  return 0;
}

mjtNum stepper_act_bias(const mjModel* m, const mjData* d, int id) {
  const mjtNum* u = stepper_params(m, id);
  if (!u) return next_bias ? next_bias(m, d, id) : 0;
  if (u[USER_KIND] == KIND_CIRCUIT && m->actuator_actnum[id] == 4) return circuit_torque(m, d, id, u);
  if (u[USER_KIND] == KIND_PHYSICAL) return physical_torque(m, d, id, u);
  return 0;
}
