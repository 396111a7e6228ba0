// Passive forces of a machine model that MuJoCo has no native element for:
// kinetic friction laws (Stribeck/Tustin/Hess-Soom, position-dependent Coulomb level)
// the fabric load on the needle, and the supply's voltage limit on the motor. Installed as mjcb_passive (process-global), so it
// acts only on models carrying the custom numerics written by mechanism/friction.py and
// mechanism/loads.py, and leaves every other model untouched.
//
// Friction split (see mechanism/friction.py): the joint's native frictionloss holds the
// static (break-away) level, which MuJoCo's constraint solver enforces exactly at rest;
// this callback (1) sets that level per step for position-dependent friction by editing
// the friction-loss row of the current constraint set, and (2) while sliding, adds back
// the part of the static level that the kinetic law does not have, so the net friction
// follows the kinetic law. Near zero velocity the added torque fades out and the
// constraint alone holds the joint.

#include <math.h>
#include <string.h>
#include <mujoco/mujoco.h>

#define FRICTION_FIELDS 12
#define LOAD_FIELDS 9
#define SUPPLY_FIELDS 8

static int find_numeric(const mjModel* m, const char* name) {
  for (int i = 0; i < m->nnumeric; i++) {
    if (strcmp(m->names + m->name_numericadr[i], name) == 0) return i;
  }
  return -1;
}

// smooth sign: v/sqrt(v^2+eps^2), exact sign well above eps
static mjtNum smooth_sign(mjtNum v, mjtNum eps) { return v / sqrt(v * v + eps * eps); }

// Must match friction.py: the Stribeck shape S(v) in [0, 1], 1 at rest.
mjtNum mechanism_stribeck_shape(int law, mjtNum v, mjtNum vs, mjtNum delta) {
  if (law == 0 || vs <= 0) return 0;
  mjtNum x = fabs(v) / vs;
  if (law == 1) return exp(-pow(x, delta));  // Tustin
  return 1.0 / (1.0 + x * x);                // Hess and Soom
}

static void apply_friction(const mjModel* m, mjData* d, const mjtNum* p, int n) {
  // p: [version, count, then count * FRICTION_FIELDS]
  int count = (int)p[1];
  if (n < 2 + count * FRICTION_FIELDS) return;
  for (int k = 0; k < count; k++) {
    const mjtNum* f = p + 2 + k * FRICTION_FIELDS;
    int dof = (int)f[0], qadr = (int)f[1], law = (int)f[5];
    mjtNum coulomb = f[2], stat = f[3], vs = f[4], delta = f[6];
    mjtNum amp = f[7], phase = f[8], harmonic = f[9], eps = f[10], static_amp = f[11];
    mjtNum wave = qadr >= 0 ? cos(harmonic * d->qpos[qadr] - phase) : 0;
    mjtNum scale = 1.0 + amp * wave;                  // running level
    mjtNum level = stat * (1.0 + static_amp * wave);  // the static level the constraint holds now
    for (int r = 0; r < d->nefc; r++) {
      if (d->efc_type[r] == mjCNSTR_FRICTION_DOF && d->efc_id[r] == dof) {
        d->efc_frictionloss[r] = level;
        // the island solver works on its own sorted copy of the constraint rows
        if (d->nisland > 0) d->iefc_frictionloss[d->map_efc2iefc[r]] = level;
        break;
      }
    }
    mjtNum v = d->qvel[dof];
    mjtNum kinetic = (coulomb + (stat - coulomb) * mechanism_stribeck_shape(law, v, vs, delta)) * scale;
    d->qfrc_passive[dof] += (level - kinetic) * smooth_sign(v, eps);
  }
}

static void apply_needle_load(const mjModel* m, mjData* d, const mjtNum* p, int n) {
  // p: [version, site, body, fabric_top_z, fabric_thickness, down_force, up_force, ramp, eps]
  if (n < LOAD_FIELDS) return;
  int site = (int)p[1], body = (int)p[2];
  mjtNum top = p[3], thickness = p[4], down = p[5], up = p[6], ramp = p[7], eps = p[8];
  if (site < 0 || site >= m->nsite || body < 0 || body >= m->nbody) return;
  const mjtNum* tip = d->site_xpos + 3 * site;
  mjtNum depth = top - tip[2];  // how far the point is below the fabric's top surface
  if (depth <= 0) return;
  mjtNum vel[6];
  mj_objectVelocity(m, d, mjOBJ_SITE, site, vel, 0);  // world frame: vel[3..5] linear
  mjtNum vz = vel[5];
  // Piercing (moving down) builds up over the point's taper and lasts until the blade is
  // through the stack; after that, and while withdrawing, only the blade's drag remains.
  mjtNum engaged = depth < ramp ? depth / ramp : 1.0;
  mjtNum piercing = vz < 0 && depth < thickness + ramp;
  mjtNum magnitude = (piercing ? down : up) * engaged;
  mjtNum force[3] = {0, 0, -magnitude * smooth_sign(vz, eps)};
  mjtNum torque[3] = {0, 0, 0};
  mj_applyFT(m, d, force, torque, tip, body, d->qfrc_passive);
}

// Must match mechanism/physics/motor.py SupplyLimit: the supply cannot put more than
// supply_V - series_ohm * I on the motor terminals, so the current is the smaller of the
// commanded one and (supply_V - Ke w) / (R + series_ohm); the difference is taken back here.
static void apply_supply_limit(const mjModel* m, mjData* d, const mjtNum* p, int n) {
  // p: [version, actuator, dof, supply_V, series_ohm, resistance_ohm, kt, ke]
  if (n < SUPPLY_FIELDS) return;
  int act = (int)p[1], dof = (int)p[2];
  if (act < 0 || act >= m->nu || dof < 0 || dof >= m->nv) return;
  mjtNum vs = p[3], rs = p[4], r = p[5], kt = p[6], ke = p[7];
  mjtNum emf = ke * d->qvel[dof];
  mjtNum commanded = (d->ctrl[act] - emf) / r;
  mjtNum high = (vs - emf) / (r + rs), low = (-vs - emf) / (r + rs);
  if (commanded > high && commanded > 0) d->qfrc_passive[dof] += kt * (high - commanded);
  if (commanded < low && commanded < 0) d->qfrc_passive[dof] += kt * (low - commanded);
}

// Must match mechanism/physics/motor.py ServoDrive: the actuator carries the unsaturated loop
// Kt/R (kp (goal - q) - (kd + Ke) q'); the driver's voltage is clipped at +-limit, so the
// difference Kt/R (clip(V) - V) is added here.
#define SERVO_FIELDS 9
static void apply_servo_limit(const mjModel* m, mjData* d, const mjtNum* p, int n) {
  // p: [version, count, count x (actuator, dof, qadr, limit_V, kp, kd, R, Kt, Ke)]
  if (n < 2) return;
  int count = (int)p[1];
  for (int k = 0; k < count && 2 + SERVO_FIELDS * (k + 1) <= n; k++) {
    const mjtNum* s = p + 2 + SERVO_FIELDS * k;
    int act = (int)s[0], dof = (int)s[1], qadr = (int)s[2];
    if (act < 0 || act >= m->nu || dof < 0 || dof >= m->nv || qadr < 0 || qadr >= m->nq) continue;
    mjtNum limit = s[3], kp = s[4], kd = s[5], r = s[6], kt = s[7];
    mjtNum wanted = kp * (d->ctrl[act] - d->qpos[qadr]) - kd * d->qvel[dof];
    mjtNum applied = wanted > limit ? limit : (wanted < -limit ? -limit : wanted);
    d->qfrc_passive[dof] += kt / r * (applied - wanted);
  }
}

void mechanism_passive(const mjModel* m, mjData* d) {
  int i = find_numeric(m, "mechanism_friction");
  if (i >= 0) apply_friction(m, d, m->numeric_data + m->numeric_adr[i], m->numeric_size[i]);
  i = find_numeric(m, "mechanism_needle_load");
  if (i >= 0) apply_needle_load(m, d, m->numeric_data + m->numeric_adr[i], m->numeric_size[i]);
  i = find_numeric(m, "mechanism_supply");
  if (i >= 0) apply_supply_limit(m, d, m->numeric_data + m->numeric_adr[i], m->numeric_size[i]);
  i = find_numeric(m, "mechanism_servo");
  if (i >= 0) apply_servo_limit(m, d, m->numeric_data + m->numeric_adr[i], m->numeric_size[i]);
}
