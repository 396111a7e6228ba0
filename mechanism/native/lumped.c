/* The lumped sewing-machine drive (thesis eq. 15-16), arm side, over many segments.
 *
 * One degree of freedom (rigid belt) or two (elastic belt: motor and arm masses joined
 * by a spring-damper), driven by per-sample coefficient arrays that the Python effect
 * library fills (see mechanism/lumped.py, which holds the same equations in numpy).
 *
 *   J(t) w' = g U(t) - c_emf w - cv(t) w - tau_motor(t) - tau_arm(t) - Q(t) w^2
 *             - [Fk(t) + Fx(t) exp(-(|w|/ws)^delta)] sgn(w)
 *
 * Stick-slip (Karnopp): a shaft at rest stays at rest while the driving torque is within
 * the static level Fk + Fx; a velocity that would cross zero within a step stops at zero.
 * The linear damping is integrated exactly over a step (exponential integrator), the rest
 * at a half-step prediction (exponential midpoint, second order). Position-dependent
 * coefficients are evaluated by the caller at the mid-sample angle. Output: arm velocity at every sample of every segment.
 */
#include <limits.h>
#include <math.h>

typedef struct {
    double gain;      /* n Kt / R  [Nm/V], arm side */
    double c_emf;     /* n^2 Kt Ke / R [Nm s/rad], arm side */
    double ws;        /* Stribeck velocity [rad/s] (arm) */
    double delta;     /* Stribeck exponent */
    double k_belt;    /* belt stiffness, arm-side units [Nm/rad]; 0 = rigid belt */
    double c_belt;    /* belt damping [Nm s/rad] */
    double j_motor;   /* motor-side inertia share, arm units [kg m^2] (belt mode) */
    double dt;        /* sample step [s] */
    int substeps;
    double gap;       /* backlash: half the belt's free play, arm units [rad] (belt mode) */
} drive_params;

static double sgn(double x) { return (x > 0) - (x < 0); }

static double friction_level(double fk, double fx, double w, double ws, double delta) {
    if (fx == 0.0) return fk;
    double r = fabs(w) / ws;
    return fk + fx * exp(-pow(r, delta));
}

/* Rigid belt: one velocity state. Exponential midpoint rule: the linear damping exactly,
 * the velocity-dependent rest (1/2 J' w^2, Stribeck) at a half-step prediction. */
typedef struct {
    const double *u, *tm, *ta, *fk, *fx, *cv, *jt, *q;
} coefficients;

/* the decays depend on the damping and the inertia only, which are constant over long
 * stretches (often the whole recording): computed again only when either changes */
typedef struct {
    double c, j, decay, decay_half;
    double fx, fade;   /* Stribeck: above the speed ratio ``fade`` the excess no longer changes fk + fx e^... */
    int fk_exponent;   /* ... which depends on fk only through its binary exponent */
} decays;

/* The speed ratio |w|/ws above which fk + fx exp(-(|w|/ws)^delta) rounds to fk exactly: the
 * excess is then below a quarter of fk's last bit (a factor e to spare, and 1e-9 for the
 * rounding of pow and log). Infinite where no such ratio is safe (fk 0, fx not positive). */
static int fade_key(double fk) {
    /* fade_ratio's only dependence on fk: infinite (0, not finite) or the exponent e with
     * |fk| in [2^(e-1), 2^e), whose last bit is 2^(e-53) */
    if (fk == 0.0 || !isfinite(fk)) return INT_MIN;
    int e;
    frexp(fabs(fk), &e);
    return e;
}

static double fade_ratio(int e, double fx, double delta) {
    if (!(fx > 0.0) || e == INT_MIN) return INFINITY;
    double x = log(fx / ldexp(1.0, e - 55)) + 1.0;
    if (!(x > 1.0)) x = 1.0;
    return pow(x, 1.0 / delta) * (1.0 + 1e-9);
}

static inline double friction_faded(double fk, double fx, double w, double ws, double delta, double fade) {
    if (fx == 0.0) return fk;
    double r = fabs(w) / ws;
    if (r > fade) return fk;                   /* what the formula below rounds to */
    return fk + fx * exp(-pow(r, delta));
}

static inline double rigid_step(const drive_params *p, const coefficients *a, int k, double w, double h, decays *d) {
    double c = p->c_emf + a->cv[k];
    if (c != d->c || a->jt[k] != d->j) {
        d->c = c;
        d->j = a->jt[k];
        d->decay = exp(-c * h / a->jt[k]);
        d->decay_half = exp(-0.5 * c * h / a->jt[k]);
    }
    double decay = d->decay, decay_half = d->decay_half;
    double drive = p->gain * a->u[k] - a->tm[k] - a->ta[k];
    double fk = a->fk[k], fx = a->fx[k], q = a->q[k];
    if (fx != 0.0) {
        /* fk changes at every sample under a drift or a position-dependent friction; the fade
         * ratio (a log and a pow) only when fx or fk's binary exponent does */
        int e = fade_key(fk);
        if (e != d->fk_exponent || fx != d->fx) {
            d->fk_exponent = e;
            d->fx = fx;
            d->fade = fade_ratio(e, fx, p->delta);
        }
    }
    for (int s = 0; s < p->substeps; s++) {
        double f = drive - q * w * w;
        double dir = sgn(w);
        if (w == 0.0) {
            if (fabs(f) <= fk + fx) continue;   /* stuck */
            dir = sgn(f);
        }
        double wss = (f - friction_faded(fk, fx, w, p->ws, p->delta, d->fade) * dir) / c;
        double wh = wss + (w - wss) * decay_half;
        if (sgn(wh) == -dir) wh = 0.0;
        f = drive - q * wh * wh - friction_faded(fk, fx, wh, p->ws, p->delta, d->fade) * dir;
        wss = f / c;
        double wn = wss + (w - wss) * decay;
        if (sgn(wn) == -dir) wn = 0.0;              /* stops within the step */
        w = wn;
    }
    return w;
}

static void run_rigid(const drive_params *p, const coefficients *a, int start, int length, double w0, double *out) {
    double w = w0;
    double h = p->dt / p->substeps;
    decays d = {NAN, NAN, 0.0, 0.0, NAN, INFINITY, INT_MAX};
    for (int i = 0; i < length; i++) {
        out[i] = w;
        w = rigid_step(p, a, start + i, w, h, &d);
    }
}

/* Four segments of one length side by side: the same steps (the same numbers) as one at a
 * time, but four independent chains of dependent arithmetic keep the processor busy. */
#define LANES 4
static void run_rigid_lanes(const drive_params *p, const coefficients *a, const int *starts, int length,
                            const double *w0, double *const *out, int lanes) {
    double w[LANES];
    decays d[LANES];
    double h = p->dt / p->substeps;
    if (lanes < LANES) {
        for (int i = 0; i < length; i++)
            for (int l = 0; l < lanes; l++) {
                if (i == 0) {
                    w[l] = w0[l];
                    d[l].c = d[l].j = NAN;
                    d[l].decay = d[l].decay_half = 0.0;
                    d[l].fx = NAN;
                    d[l].fade = INFINITY;
                    d[l].fk_exponent = INT_MAX;
                }
                out[l][i] = w[l];
                w[l] = rigid_step(p, a, starts[l] + i, w[l], h, &d[l]);
            }
        return;
    }
    for (int l = 0; l < LANES; l++) {
        w[l] = w0[l];
        d[l].c = NAN;
        d[l].j = NAN;
        d[l].decay = d[l].decay_half = 0.0;
        d[l].fx = NAN;
        d[l].fade = INFINITY;
        d[l].fk_exponent = INT_MAX;
    }
    for (int i = 0; i < length; i++) {
        for (int l = 0; l < LANES; l++) {
            out[l][i] = w[l];
            w[l] = rigid_step(p, a, starts[l] + i, w[l], h, &d[l]);
        }
    }
}

/* Elastic belt: motor velocity wm, arm velocity w, belt twist x (arm units). Motor torque,
 * back-emf, the viscous friction (the model's is the motor's, as the thesis's b_m) and the
 * motor-angle-periodic torque act on the motor; Coulomb friction, position loads and the
 * linkage on the arm. Semi-implicit Euler with enough substeps. */
typedef struct {
    double w, wm, x;
    int nsub;
    double h;
} belt_state;

static belt_state belt_start(const drive_params *p, const coefficients *a, int start, double w0) {
    double jm = p->j_motor;
    double kb = p->k_belt;
    int k0 = start;
    belt_state b;
    double w = w0;
    b.w = w0;
    b.wm = w0;
    double ja0 = a->jt[k0] - jm;
    double wr = sqrt(kb * (1.0 / jm + 1.0 / ja0));
    int nsub = p->substeps;
    int need = (int)ceil(wr * p->dt / 0.25);
    if (need > nsub) nsub = need;
    b.nsub = nsub;
    b.h = p->dt / nsub;
    /* quasi-static initial twist: the belt carries the arm's load (the viscous friction is the
     * motor's: its bearings and its winding's damping) */
    double load = a->ta[k0] + a->q[k0] * w * w + (w != 0.0 ? a->fk[k0] * sgn(w) : 0.0);
    if (w == 0.0) {
        double drive = p->gain * a->u[k0] - a->tm[k0];
        double lim = a->fk[k0] + a->fx[k0];
        load = drive > lim ? lim : (drive < -lim ? -lim : drive);
    }
    b.x = load / kb + (load > 0 ? p->gap : (load < 0 ? -p->gap : 0.0));
    return b;
}

static inline void belt_step(const drive_params *p, const coefficients *a, int k, belt_state *b) {
    double jm = p->j_motor;
    double kb = p->k_belt, cb = p->c_belt;
    double w = b->w, wm = b->wm, x = b->x, h = b->h;
    double ja = a->jt[k] - jm;
    for (int s = 0; s < b->nsub; s++) {
        double fb = x > p->gap ? kb * (x - p->gap) + cb * (wm - w)
                  : (x < -p->gap ? kb * (x + p->gap) + cb * (wm - w) : 0.0);   /* free play: no torque */
        double fm = p->gain * a->u[k] - (p->c_emf + a->cv[k]) * wm - a->tm[k] - fb;
        wm += h * fm / jm;
        double f = fb - a->ta[k] - a->q[k] * w * w;
        double dir = sgn(w);
        int stuck = 0;
        if (w == 0.0) {
            if (fabs(f) <= a->fk[k] + a->fx[k]) stuck = 1;
            else dir = sgn(f);
        }
        if (!stuck) {
            f -= friction_level(a->fk[k], a->fx[k], w, p->ws, p->delta) * dir;
            double wn = w + h * f / ja;
            if (sgn(wn) == -dir) wn = 0.0;
            w = wn;
        }
        x += h * (wm - w);
    }
    b->w = w;
    b->wm = wm;
    b->x = x;
}

static void run_belt(const drive_params *p, const coefficients *a, int start, int length, double w0, double *out) {
    belt_state b = belt_start(p, a, start, w0);
    for (int i = 0; i < length; i++) {
        out[i] = b.w;
        belt_step(p, a, start + i, &b);
    }
}

/* Up to LANES segments of one length and one substep count side by side (as the rigid
 * lanes: the same numbers as one at a time). Returns 0, having done nothing, when the
 * segments need different substep counts. */
static int run_belt_lanes(const drive_params *p, const coefficients *a, const int *starts, int length,
                          const double *w0, double *const *out, int lanes) {
    belt_state b[LANES];
    for (int l = 0; l < lanes; l++) {
        b[l] = belt_start(p, a, starts[l], w0[l]);
        if (b[l].nsub != b[0].nsub) return 0;
    }
    for (int i = 0; i < length; i++)
        for (int l = 0; l < lanes; l++) {
            out[l][i] = b[l].w;
            belt_step(p, a, starts[l] + i, &b[l]);
        }
    return 1;
}

/* Simulate n_seg segments; segment j starts at sample starts[j] with velocity w0[j] and
 * runs lengths[j] samples; its velocities go to out[offsets[j] ...]. */
void simulate_segments(const drive_params *p, const double *u, const double *tm, const double *ta,
                       const double *fk, const double *fx, const double *cv, const double *jt,
                       const double *q, int n_seg, const int *starts, const int *lengths,
                       const int *offsets, const double *w0, double *out) {
    coefficients a = {u, tm, ta, fk, fx, cv, jt, q};
    int belt = p->k_belt > 0.0;
    int j = 0;
    while (j + 1 < n_seg) {
        int lanes = n_seg - j < LANES ? n_seg - j : LANES;
        int same = 1;
        for (int l = 1; l < lanes; l++) same &= lengths[j + l] == lengths[j];
        if (!same) break;
        double *o[LANES];
        for (int l = 0; l < lanes; l++) o[l] = out + offsets[j + l];
        if (belt) {
            if (!run_belt_lanes(p, &a, starts + j, lengths[j], w0 + j, o, lanes)) break;
        } else {
            run_rigid_lanes(p, &a, starts + j, lengths[j], w0 + j, o, lanes);
        }
        j += lanes;
    }
    for (; j < n_seg; j++) {
        if (belt)
            run_belt(p, &a, starts[j], lengths[j], w0[j], out + offsets[j]);
        else
            run_rigid(p, &a, starts[j], lengths[j], w0[j], out + offsets[j]);
    }
}

/* The angle from the simulated velocity by trapezoids, each segment from its start angle:
 * angle[0] = a0, angle[i] = (sum of 0.5 (w[k] + w[k-1]), k <= i) dt + a0. The same operations
 * in the same order as the numpy fallback (add, halve, running sum, scale, shift): equal numbers. */
void angle_from_velocity(const double *w, int n_seg, int length, double dt, const double *a0,
                         double *angle) {
    for (int j = 0; j < n_seg; j++) {
        const double *v = w + (long)j * length;
        double *a = angle + (long)j * length;
        double s = 0.0;
        a[0] = 0.0 * dt + a0[j];
        for (int i = 1; i < length; i++) {
            s += (v[i] + v[i - 1]) * 0.5;
            a[i] = s * dt + a0[j];
        }
    }
}

/* out[j] = sum_k x[first[j] + k] c[k]: a filter evaluated only at the samples it is needed
 * (the velocity differentiator at the scored samples), without gathering the windows. */
void windowed_dot(const double *x, int n, const long long *first, const double *c, int m,
                  double *out) {
    int j = 0;
    /* four outputs at a time: four independent chains of additions (each still in order k) */
    for (; j + 4 <= n; j += 4) {
        const double *x0 = x + first[j], *x1 = x + first[j + 1];
        const double *x2 = x + first[j + 2], *x3 = x + first[j + 3];
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
        for (int k = 0; k < m; k++) {
            s0 += x0[k] * c[k];
            s1 += x1[k] * c[k];
            s2 += x2[k] * c[k];
            s3 += x3[k] * c[k];
        }
        out[j] = s0;
        out[j + 1] = s1;
        out[j + 2] = s2;
        out[j + 3] = s3;
    }
    for (; j < n; j++) {
        const double *xj = x + first[j];
        double s = 0.0;
        for (int k = 0; k < m; k++) s += xj[k] * c[k];
        out[j] = s;
    }
}
