/* Truth model of the virtual test bench (mechanism.testbench): the sewing machine's
 * DC motor, belt, arm shaft, friction and concealed effects, integrated with fixed
 * sub-steps. The Python twin is mechanism/testbench/simulate.py (_simulate_python);
 * both must follow the same algorithm step for step (a test compares them).
 *
 * Scheme per sub-step h: the armature current first (implicit in R/L), then velocities
 * (semi-implicit: linear damping implicit, set-valued Coulomb friction solved exactly,
 * which gives true sticking with no creep), then angles from the new velocities
 * (symplectic Euler). Friction acts on the arm shaft; a stuck arm stays stuck while the
 * other torques stay within the static level.
 */
#include <math.h>

/* All doubles, in this order: mirrored by the ctypes Structure in simulate.py. */
typedef struct {
    double dt, n_sub, belt;
    double R, L, Kt, Ke, ratio;
    double J_motor, J_arm0, d_motor, coulomb;
    double pf_a1, pf_p1, pf_a2, pf_p2;
    double st_model, st_excess, st_velocity, st_exponent;
    double th_coulomb_drop, th_viscous_drop, th_tau_warm, th_tau_cool;
    double rp_a1, rp_p1, rp_ac, rp_pc, rp_nc, motor_phase0;
    double lk_mass, lk_r, lk_l, gravity;
    double nd_force_per_m, nd_fabric, nd_point, nd_sliding, nd_depth_bdc;
    double belt_k, belt_c;
    double bl_gap;   /* backlash: half the free play of the belt/gear, arm-side angle [rad] */
    double stop_on, stop_lo, stop_hi;   /* hard stops on the arm (shaft) angle [rad]: inelastic */
    double tb_n, tb_lo, tb_hi;   /* linkage table over [tb_lo, tb_hi] (shaft angle): tb_n rows of J_var, J'/2, G */
} tb_params;

static const double TWO_PI = 6.283185307179586;

static double clamp(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* Slider (needle bar) height above the crank centre and its first two derivatives. */
static void slider(const tb_params *p, double th, double *z, double *dz, double *ddz) {
    double s = sin(th), c = cos(th), r = p->lk_r;
    double S = sqrt(p->lk_l * p->lk_l - r * r * s * s);
    double g = r * r * s * c;
    *z = r * c + S;
    *dz = -r * s - g / S;
    *ddz = -r * c - r * r * (c * c - s * s) / S - g * g / (S * S * S);
}

/* Length of [a, b] inside [0, T]. */
static double overlap(double a, double b, double T) {
    double lo = a > 0.0 ? a : 0.0, hi = b < T ? b : T;
    return hi > lo ? hi - lo : 0.0;
}

/* Resisting torque of the fabric on the arm [N m] (forward sewing). */
static double needle_torque(const tb_params *p, double th) {
    if (p->nd_force_per_m <= 0.0) return 0.0;
    double z, dz, ddz;
    slider(p, th, &z, &dz, &ddz);
    double tip = z - (p->lk_l - p->lk_r) - p->nd_depth_bdc;   /* tip height above the needle plate */
    double depth = p->nd_fabric - tip;           /* tip depth below the fabric top */
    if (depth <= 0.0) return 0.0;
    double shank = overlap(-1e9, depth - p->nd_point, p->nd_fabric);
    double force = p->nd_sliding * shank;
    double phase = th - TWO_PI * floor(th / TWO_PI);
    if (phase < M_PI) force += overlap(depth - p->nd_point, depth, p->nd_fabric); /* piercing */
    return p->nd_force_per_m * force * fabs(dz);
}

/* Kinetic and static Coulomb levels on the arm [N m]. */
static void friction_levels(const tb_params *p, double th, double speed, double warmth,
                            double *kinetic, double *stat) {
    double level = p->coulomb * (1.0 - p->th_coulomb_drop * warmth);
    level *= 1.0 + p->pf_a1 * cos(th - p->pf_p1) + p->pf_a2 * cos(2.0 * th - p->pf_p2);
    double decay = 0.0;
    if (p->st_model == 1.0) decay = exp(-pow(speed / p->st_velocity, p->st_exponent));
    else if (p->st_model == 2.0) decay = 1.0 / (1.0 + (speed / p->st_velocity) * (speed / p->st_velocity));
    double fabric = needle_torque(p, th);
    *kinetic = level * (1.0 + p->st_excess * decay) + fabric;
    *stat = level * (1.0 + p->st_excess) + fabric;
}

/* Torque through the belt: spring-damper beyond the free play, nothing inside it. */
static double belt_torque(const tb_params *p, double twist, double rate) {
    double gap = p->bl_gap;
    if (twist > gap) return p->belt_k * (twist - gap) + p->belt_c * rate;
    if (twist < -gap) return p->belt_k * (twist + gap) + p->belt_c * rate;
    return 0.0;
}

static double ripple(const tb_params *p, double thm) {
    return p->rp_a1 * sin(thm + p->rp_p1) + p->rp_ac * sin(p->rp_nc * thm + p->rp_pc);
}

/* The linkage table at shaft angle th (linear, held at the ends): the inertia's variation
 * about J_arm0, half its derivative and the gravity torque (positive resisting). */
static void linkage_table(const tb_params *p, const double *table, double th, double *jv, double *hdj, double *g) {
    int n = (int)p->tb_n;
    double x = (th - p->tb_lo) / (p->tb_hi - p->tb_lo) * (n - 1);
    if (x <= 0.0) x = 0.0;
    if (x >= n - 1) x = n - 1;
    int i = (int)x;
    if (i > n - 2) i = n - 2;
    double f = x - i;
    *jv = table[3 * i] + f * (table[3 * i + 3] - table[3 * i]);
    *hdj = table[3 * i + 1] + f * (table[3 * i + 4] - table[3 * i + 1]);
    *g = table[3 * i + 2] + f * (table[3 * i + 5] - table[3 * i + 2]);
}

/* Exact implicit step of M dv/dt = tau - c v - f, f in F sgn(v): returns v(t+h). */
static double friction_step(double M, double v, double h, double tau, double c, double kinetic, double stat) {
    double level = v == 0.0 ? stat : kinetic;
    double impulse = M * v / h + tau;
    if (fabs(impulse) <= level) return 0.0;
    return (impulse - copysign(level, impulse)) / (M / h + c);
}

/* state: theta_arm, omega_arm, theta_motor, omega_motor, current, warmth (updated in place).
 * u[k]: applied voltage over [t_k, t_k + dt). Outputs: the state at t_k, k = 0..n-1.
 * table: tb_n rows (J_var, J'/2, G) when tb_n > 0, else unused (may be NULL). */
int tb_simulate(const tb_params *p, int n, const double *u, double *state,
                double *out_theta_a, double *out_omega_a, double *out_theta_m,
                double *out_omega_m, double *out_current, double *out_warmth, const double *table) {
    double tha = state[0], wa = state[1], thm = state[2], wm = state[3], cur = state[4], x = state[5];
    int n_sub = (int)p->n_sub;
    double h = p->dt / n_sub, N = p->ratio;
    for (int k = 0; k < n; ++k) {
        double uk = u[k];
        if (p->L <= 0.0) cur = (uk - p->Ke * wm) / p->R;
        out_theta_a[k] = tha; out_omega_a[k] = wa; out_theta_m[k] = thm;
        out_omega_m[k] = wm; out_current[k] = cur; out_warmth[k] = x;
        for (int s = 0; s < n_sub; ++s) {
            double z, dz, ddz;
            slider(p, tha, &z, &dz, &ddz);
            double M_arm = p->J_arm0 + p->lk_mass * dz * dz;
            double tau_link = -p->lk_mass * dz * ddz * wa * wa - p->lk_mass * p->gravity * dz;
            if (p->tb_n > 0.0) {
                double jv, hdj, g;
                linkage_table(p, table, tha, &jv, &hdj, &g);
                M_arm += jv;
                tau_link += -hdj * wa * wa - g;
            }
            double d = p->d_motor * (1.0 - p->th_viscous_drop * x);
            double kin, sta;
            friction_levels(p, tha, fabs(wa), x, &kin, &sta);
            double drive, damping;
            if (p->L > 0.0) {
                cur = (cur + h / p->L * (uk - p->Ke * wm)) / (1.0 + h * p->R / p->L);
                drive = p->Kt * cur;
                damping = d;
            } else {
                drive = p->Kt * uk / p->R;
                damping = d + p->Kt * p->Ke / p->R;
            }
            if (p->belt == 0.0) {
                double tau = N * (drive - ripple(p, thm)) + tau_link;
                wa = friction_step(M_arm, wa, h, tau, N * N * damping, kin, sta);
                wm = N * wa;
            } else {
                double belt = belt_torque(p, thm / N - tha, wm / N - wa);
                double tau_m = drive - ripple(p, thm) - belt / N;
                wm = (p->J_motor * wm / h + tau_m) / (p->J_motor / h + damping);
                wa = friction_step(M_arm, wa, h, belt + tau_link, 0.0, kin, sta);
            }
            tha += h * wa;
            thm += h * wm;
            if (p->stop_on != 0.0 && (tha > p->stop_hi || tha < p->stop_lo)) {
                tha = tha > p->stop_hi ? p->stop_hi : p->stop_lo;   /* inelastic: the arm stops at the stop */
                if ((tha == p->stop_hi && wa > 0.0) || (tha == p->stop_lo && wa < 0.0)) wa = 0.0;
                if (p->belt == 0.0) { thm = N * tha; wm = N * wa; }
            }
            if (p->L <= 0.0) cur = (uk - p->Ke * wm) / p->R;
            if (p->th_tau_warm > 0.0) {
                if (wa != 0.0) x += h * (1.0 - x) / p->th_tau_warm;
                else x -= h * x / p->th_tau_cool;
            }
        }
    }
    state[0] = tha; state[1] = wa; state[2] = thm; state[3] = wm; state[4] = cur; state[5] = x;
    return 0;
}
