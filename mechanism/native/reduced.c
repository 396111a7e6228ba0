// The reduced 1-DOF sewing-machine equation (mechanism/reduced.py has the derivation and
// the numpy reference of every term):
//   J(θ) θ'' = motor(θ, θ', V) + cogging(θ) - ½ J'(θ) θ'² - G(θ) - viscous(θ) θ'
//              - Σ_j r_j(θ) F_j(r_j θ') s_j(θ) sgn(r_j θ') + fabric(θ, θ')
// integrated with RK4 and Karnopp stick-slip: at rest the arm stays put while the drive
// torque is within the break-away level Σ |r_j| Fs_j s_j.
#include <math.h>

typedef struct {
  const double *inertia, *dinertia, *gravity, *motor_ratio, *viscous, *cogging;
  const double *needle_depth, *needle_dz;
  const double *friction_ratio, *friction_scale, *friction_static_scale;  // nfriction x n each
  const double *friction_params;                                          // nfriction x 5
  int n, nfriction;
  double kt, ke, resistance;
  double supply_V, series_ohm;  // series_ohm 0: no supply limit (mechanism/physics/motor.py SupplyLimit)
  double fabric_down, fabric_up, fabric_thickness, fabric_ramp;
  double stick_velocity;
} Tables;

typedef struct { int i0, i1; double f; } Cell;

static Cell locate(const Tables* t, double theta) {
  double x = fmod(theta, 2 * M_PI);
  if (x < 0) x += 2 * M_PI;
  x *= t->n / (2 * M_PI);
  Cell c;
  c.i0 = (int)x;
  if (c.i0 >= t->n) c.i0 = t->n - 1;
  c.f = x - c.i0;
  c.i1 = (c.i0 + 1) % t->n;
  return c;
}

static double at(const double* a, Cell c) { return a[c.i0] * (1 - c.f) + a[c.i1] * c.f; }

static double sgn(double x) { return (x > 0) - (x < 0); }

double mechanism_stribeck_shape(int law, double v, double vs, double delta) {
  if (law == 0 || vs <= 0) return 0;
  double x = fabs(v) / vs;
  if (law == 1) return exp(-pow(x, delta));
  return 1.0 / (1.0 + x * x);
}

static double fabric_force(const Tables* t, double depth, double v) {
  if (depth <= 0 || t->fabric_down <= 0) return 0;
  double engaged = depth / t->fabric_ramp;
  if (engaged > 1) engaged = 1;
  int piercing = v < 0 && depth < t->fabric_thickness + t->fabric_ramp;
  double magnitude = (piercing ? t->fabric_down : t->fabric_up) * engaged;
  return -magnitude * v / sqrt(v * v + 1e-6);
}

// Everything but inertia, at the arm [N m].
static double force(const Tables* t, double theta, double omega, double volts) {
  Cell c = locate(t, theta);
  double rm = at(t->motor_ratio, c);
  double emf = t->ke * rm * omega;
  double current = (volts - emf) / t->resistance;
  if (t->series_ohm > 0) {
    double high = (t->supply_V - emf) / (t->resistance + t->series_ohm);
    double low = (-t->supply_V - emf) / (t->resistance + t->series_ohm);
    if (current > high && current > 0) current = high;
    if (current < low && current < 0) current = low;
  }
  double f = rm * t->kt * current;
  f += at(t->cogging, c) - 0.5 * at(t->dinertia, c) * omega * omega - at(t->gravity, c);
  f -= at(t->viscous, c) * omega;
  for (int k = 0; k < t->nfriction; k++) {
    const double* p = t->friction_params + 5 * k;
    double r = at(t->friction_ratio + k * t->n, c), s = at(t->friction_scale + k * t->n, c);
    double v = r * omega;
    double level = (p[0] + (p[1] - p[0]) * mechanism_stribeck_shape((int)p[3], v, p[2], p[4])) * s;
    f -= r * level * sgn(v);
  }
  if (t->fabric_down > 0) {
    double dz = at(t->needle_dz, c);
    f += dz * fabric_force(t, at(t->needle_depth, c), dz * omega);
  }
  return f;
}

static double breakaway(const Tables* t, double theta) {
  Cell c = locate(t, theta);
  double total = 0;
  for (int k = 0; k < t->nfriction; k++) {
    double r = at(t->friction_ratio + k * t->n, c), s = at(t->friction_static_scale + k * t->n, c);
    total += fabs(r) * t->friction_params[5 * k + 1] * s;
  }
  return total;
}

static double accel(const Tables* t, double theta, double omega, double volts) {
  return force(t, theta, omega, volts) / at(t->inertia, locate(t, theta));
}

// volts: one value per substep; out: per sample (theta, omega, mean acceleration).
void mechanism_reduced_run(const Tables* t, const double* volts, int nvolts, int substeps, double dt,
                           double theta, double omega, double* out) {
  int nsample = nvolts / substeps;
  for (int k = 0; k < nsample; k++) {
    double start = omega;
    for (int s = 0; s < substeps; s++) {
      double v = volts[k * substeps + s];
      if (omega == 0) {
        double drive = force(t, theta, 0, v);
        if (fabs(drive) <= breakaway(t, theta)) continue;
        omega = sgn(drive) * t->stick_velocity;
      }
      double k1 = accel(t, theta, omega, v);
      double k2 = accel(t, theta + 0.5 * dt * omega, omega + 0.5 * dt * k1, v);
      double k3 = accel(t, theta + 0.5 * dt * (omega + 0.5 * dt * k1), omega + 0.5 * dt * k2, v);
      double k4 = accel(t, theta + dt * (omega + 0.5 * dt * k2), omega + dt * k3, v);
      double new_theta = theta + dt * omega + dt * dt / 6 * (k1 + k2 + k3);
      double new_omega = omega + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
      if (omega * new_omega < 0) new_omega = 0;  // came to rest within the step
      theta = new_theta;
      omega = new_omega;
    }
    out[3 * k] = theta;
    out[3 * k + 1] = omega;
    out[3 * k + 2] = (omega - start) / (dt * substeps);
  }
}
