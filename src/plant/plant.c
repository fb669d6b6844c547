/* The virtual laboratory: physical substructure, bilinear leg, shaker, sensors (see plant.h). */
#include "rths/plant.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Runge-Kutta substeps per segment of a sample whose kink crossing the exact path splits off */
#define CROSSING_SUBSTEPS 8

/* The exact discretisation of one side of the leg (or the linear plant): over a sample,
 * z_{k+1} = phi z_k + g_target_start T0 + g_target_slope (T1 - T0) + g_static
 *         + forcing amplitude x (g_forcing_cos cos theta + g_forcing_sin sin theta)
 * for the force target ramping from T0 to T1 (equal for a DAC step) and the forcing
 * amplitude cos(theta + omega tau) on an internal physical DoF. */
typedef struct {
    double *phi; /* nz x nz, row-major */
    double *g_target_start, *g_target_slope, *g_static;
    double *g_forcing_cos, *g_forcing_sin;
    double forcing_omega; /* the omega g_forcing_* were computed for; NAN: not yet */
} exact_side;

struct rths_plant {
    rths_plant_options opt;
    int n; /* physical DoFs, interface last */
    double h;
    double *minv, *c, *k;     /* n x n */
    double *static_force;     /* n */
    int leg_lower, leg_upper; /* physical indices (-1: ground), leg_upper < 0: no bilinear leg */
    double leg_extra_k;       /* (ratio - 1) k added in compression */
    double leg_k, leg_ratio;
    double *z;          /* state: q (n), v (n), then the shaker force when it lags */
    double *q, *v, fs;  /* q = z, v = z + n; shaker force */
    double *z_next;     /* nz */
    double *rk;         /* scratch: Runge-Kutta stages 10 n, forces n */
    int nz;             /* 2n, + 1 with the lag */
    exact_side side[2]; /* 0: extension (or no leg), 1: compression */
    double time_s;
    double *delay_line;
    int delay_samples, delay_pos;
    double lag_rate;          /* 2 pi f_c, 0: no lag */
    double last_force_target; /* gain x demand of the previous sample (linear hold) */
    double armature_kg;
    int forcing_index; /* internal physical forcing DoF, -1: none */
    double forcing_amplitude, forcing_theta, forcing_omega, forcing_now;
    rths_rng rng;
};

void rths_plant_defaults(rths_plant_options *opt) {
    memset(opt, 0, sizeof *opt);
    opt->gain_n_per_v = 50.0;
    opt->delay_s = 2.5e-4;
    opt->lag_cutoff_hz = 1000.0;
    opt->armature_mass_kg = 0.1;
    opt->noise = 1;
    opt->seed = 1;
    /* 0: the exact discretisation (the kink crossing located inside the sample); n >= 1:
     * classical Runge-Kutta with n substeps per sample (rig.plant_integrator: rk4) */
    opt->substeps_per_sample = 0;
    /* the amplifier's reconstruction filter: the force ramps between samples. With a bare DAC
     * step (rig.shaker.hold: step) the numerical side, which only sees samples, lags the
     * staircase force by a fraction of a sample: -0.77 % at the seed's peak for p = 0.33. */
    opt->linear_hold = 1;
    /* realistic small noise; gain errors and offsets are available but off by default, so the
     * default rig is unbiased and its results scatter only by noise */
    opt->laser = (rths_sensor_spec){0, 0, 1e-7, 1e-8};
    opt->accelerometer = (rths_sensor_spec){0, 0, 1e-2, 1e-4};
    opt->load_cell = (rths_sensor_spec){0, 0, 1e-2, 1e-4};
}

void rths_plant_ideal(rths_plant_options *opt) {
    opt->delay_s = 0;
    opt->lag_cutoff_hz = 0;
    opt->armature_mass_kg = 0;
    opt->noise = 0;
    opt->linear_hold = 1;
}

void rths_plant_destroy(rths_plant *p) {
    if (!p) return;
    free(p->minv), free(p->c), free(p->k), free(p->static_force);
    free(p->z), free(p->z_next), free(p->rk), free(p->delay_line);
    for (int s = 0; s < 2; s++) {
        exact_side *e = &p->side[s];
        free(e->phi), free(e->g_target_start), free(e->g_target_slope), free(e->g_static);
        free(e->g_forcing_cos), free(e->g_forcing_sin);
    }
    free(p);
}

/* Stiffness of one side: K, plus the leg's extra compression stiffness on side 1. */
static void side_stiffness(const rths_plant *p, int compressed, double *kk) {
    int n = p->n;
    memcpy(kk, p->k, sizeof(double) * (size_t)n * (size_t)n);
    if (!compressed || p->leg_upper < 0) return;
    int a = p->leg_upper, b = p->leg_lower;
    kk[a + a * n] += p->leg_extra_k;
    if (b >= 0) {
        kk[b + b * n] += p->leg_extra_k;
        kk[a + b * n] -= p->leg_extra_k;
        kk[b + a * n] -= p->leg_extra_k;
    }
}

/* Continuous state matrix of one side into a (ld x ld, top-left nz x nz block). */
static void side_state_matrix(const rths_plant *p, int compressed, double *kk, double *a, int ld) {
    int n = p->n;
    side_stiffness(p, compressed, kk);
    for (int i = 0; i < n; i++) {
        a[i + (size_t)(n + i) * ld] = 1.0;
        for (int j = 0; j < n; j++) {
            double mk = 0, mc = 0;
            for (int l = 0; l < n; l++) {
                mk += p->minv[i + l * n] * kk[l + j * n];
                mc += p->minv[i + l * n] * p->c[l + j * n];
            }
            a[n + i + (size_t)j * ld] = -mk;
            a[n + i + (size_t)(n + j) * ld] = -mc;
        }
        if (p->lag_rate > 0) a[n + i + (size_t)(2 * n) * ld] = p->minv[i + (n - 1) * n];
    }
    if (p->lag_rate > 0) a[2 * n + (size_t)(2 * n) * ld] = -p->lag_rate;
}

/* Exact response of one side over a sample to the held target and the static force: the
 * exponential of [[A h, U h, 0], [0, 0, I h], [0, 0, 0]] with U = (target, static) input
 * columns, for inputs a(tau) = a0 + d tau (Van Loan's block form of the hold integrals). */
static int build_side(rths_plant *p, int compressed, double *kk) {
    int n = p->n, nz = p->nz, N = nz + 4;
    double *aug = rths_mat_new(N, N), *e = rths_mat_new(N, N);
    exact_side *sd = &p->side[compressed];
    sd->phi = rths_mat_new(nz, nz);
    sd->g_target_start = calloc((size_t)nz, sizeof(double));
    sd->g_target_slope = calloc((size_t)nz, sizeof(double));
    sd->g_static = calloc((size_t)nz, sizeof(double));
    sd->g_forcing_cos = calloc((size_t)nz, sizeof(double));
    sd->g_forcing_sin = calloc((size_t)nz, sizeof(double));
    sd->forcing_omega = NAN;
    int rc = aug && e && sd->phi && sd->g_target_start && sd->g_target_slope && sd->g_static &&
                     sd->g_forcing_cos && sd->g_forcing_sin
                 ? 0
                 : -1;
    if (!rc) {
        side_state_matrix(p, compressed, kk, aug, N);
        for (int i = 0; i < n; i++) {
            double target_col = p->lag_rate > 0 ? 0.0 : p->minv[i + (n - 1) * n];
            double static_col = 0;
            for (int l = 0; l < n; l++)
                static_col += p->minv[i + l * n] * p->static_force[l];
            aug[n + i + (size_t)nz * N] = target_col;
            aug[n + i + (size_t)(nz + 1) * N] = static_col;
        }
        if (p->lag_rate > 0) aug[2 * n + (size_t)nz * N] = p->lag_rate;
        aug[nz + (size_t)(nz + 2) * N] = 1.0;
        aug[nz + 1 + (size_t)(nz + 3) * N] = 1.0;
        for (size_t i = 0; i < (size_t)N * N; i++)
            aug[i] *= p->h;
        rc = rths_expm(N, aug, e);
    }
    if (!rc) {
        for (int j = 0; j < nz; j++)
            for (int i = 0; i < nz; i++)
                sd->phi[j + i * nz] = e[i + (size_t)j * N]; /* row-major: read by rows */
        for (int i = 0; i < nz; i++) {
            sd->g_target_start[i] = e[i + (size_t)nz * N];
            sd->g_static[i] = e[i + (size_t)(nz + 1) * N];
            /* d = (T1 - T0) / h */
            sd->g_target_slope[i] = e[i + (size_t)(nz + 2) * N] / p->h;
        }
    }
    rths_mat_free(aug);
    rths_mat_free(e);
    return rc;
}

/* Exact response to the forcing amplitude cos(theta + omega tau) on the forcing DoF: the
 * exponential of [[A h, b e1^T h], [0, W h]] with W the rotation generator of (cos, sin); redone
 * when omega changes (once per test frequency). */
static int build_forcing(rths_plant *p, int compressed, double omega) {
    int n = p->n, nz = p->nz, N = nz + 2;
    exact_side *sd = &p->side[compressed];
    double *aug = rths_mat_new(N, N), *e = rths_mat_new(N, N), *kk = rths_mat_new(n, n);
    int rc = aug && e && kk ? 0 : -1;
    if (!rc) {
        side_state_matrix(p, compressed, kk, aug, N);
        for (int i = 0; i < n; i++)
            aug[n + i + (size_t)nz * N] = p->minv[i + p->forcing_index * n];
        aug[nz + (size_t)(nz + 1) * N] = -omega;
        aug[nz + 1 + (size_t)nz * N] = omega;
        for (size_t i = 0; i < (size_t)N * N; i++)
            aug[i] *= p->h;
        rc = rths_expm(N, aug, e);
    }
    if (!rc) {
        for (int i = 0; i < nz; i++) {
            sd->g_forcing_cos[i] = e[i + (size_t)nz * N];
            sd->g_forcing_sin[i] = e[i + (size_t)(nz + 1) * N];
        }
        sd->forcing_omega = omega;
    }
    rths_mat_free(aug), rths_mat_free(e), rths_mat_free(kk);
    return rc;
}

static int plant_alloc(rths_plant *p, int n, int delay) {
    size_t nn = (size_t)n * (size_t)n;
    p->nz = 2 * n + (p->lag_rate > 0 ? 1 : 0);
    p->minv = calloc(nn, sizeof(double));
    p->c = calloc(nn, sizeof(double));
    p->k = calloc(nn, sizeof(double));
    p->static_force = calloc((size_t)n, sizeof(double));
    p->z = calloc((size_t)p->nz, sizeof(double));
    p->z_next = calloc((size_t)p->nz, sizeof(double));
    p->rk = calloc(11 * (size_t)n, sizeof(double)); /* RK4 stages and the force scratch */
    p->delay_line = calloc((size_t)delay + 1, sizeof(double));
    p->q = p->z;
    p->v = p->z ? p->z + n : NULL;
    return p->minv && p->c && p->k && p->static_force && p->z && p->z_next && p->rk && p->delay_line
               ? 0
               : -1;
}

/* Start at rest in static equilibrium under the preload: K q + g(q) = f_static, solved for each
 * side of the kink and kept where the assumed side is consistent. */
static int static_start(rths_plant *p) {
    int n = p->n;
    double *kk = rths_mat_new(n, n), *q = calloc((size_t)n, sizeof(double));
    if (!kk || !q) {
        free(kk), free(q);
        return -1;
    }
    for (int side = 0; side < 2; side++) {
        side_stiffness(p, side, kk);
        memcpy(q, p->static_force, sizeof(double) * (size_t)n);
        if (rths_mat_solve(n, 1, kk, q)) continue;
        double delta =
            p->leg_upper >= 0 ? q[p->leg_upper] - (p->leg_lower >= 0 ? q[p->leg_lower] : 0) : 0;
        if (p->leg_upper < 0 || (side == 0) == (delta >= 0)) {
            memcpy(p->q, q, sizeof(double) * (size_t)n);
            break;
        }
    }
    free(kk), free(q);
    return 0;
}

/* Matrices of the physical substructure in physical order (internal physical DoFs, then the
 * interface), the interface storey with the assembly's FULL mass plus the armature. */
static int plant_matrices(rths_plant *p, const rths_setup *setup) {
    const rths_split *s = &setup->split;
    int n = p->n, iface = s->int_dofs[0];
    double *m = rths_mat_new(n, n);
    if (!m) return -1;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            m[i + j * n] = RTHS_AT(s->mass_phys, n, i, j);
            p->c[i + j * n] = RTHS_AT(s->damping_phys, n, i, j);
            p->k[i + j * n] = RTHS_AT(s->stiffness_phys, n, i, j);
        }
    m[(n - 1) + (n - 1) * n] =
        RTHS_AT(setup->assembly.mass, setup->assembly.n, iface, iface) + p->opt.armature_mass_kg;
    int rc = rths_mat_inverse(n, m, p->minv);
    rths_mat_free(m);
    return rc;
}

/* Assembly DoF -> physical index (-1: not physical), malloc'ed. */
static int *physical_index(const rths_setup *setup) {
    const rths_split *s = &setup->split;
    int *to_phys = malloc((size_t)setup->assembly.n * sizeof *to_phys);
    if (!to_phys) return NULL;
    for (int i = 0; i < setup->assembly.n; i++)
        to_phys[i] = -1;
    for (int i = 0; i < s->n_phys; i++)
        to_phys[s->phys_dofs[i]] = i;
    to_phys[s->int_dofs[0]] = s->np - 1;
    return to_phys;
}

static int plant_leg_and_loads(rths_plant *p, const rths_setup *setup, const int *to_phys,
                               rths_error *err) {
    const rths_split *s = &setup->split;
    for (int i = 0; i < setup->assembly.n; i++)
        if (to_phys[i] >= 0 && setup->static_force)
            p->static_force[to_phys[i]] = setup->static_force[i];
    p->forcing_index = -1;
    for (int i = 0; i < s->n_phys; i++)
        if (s->phys_dofs[i] == setup->forcing_dof) p->forcing_index = i;
    p->leg_upper = -1;
    if (!setup->has_bilinear) return RTHS_OK;
    p->leg_upper = to_phys[setup->leg.upper_dof];
    p->leg_lower = setup->leg.lower_dof < 0 ? -1 : to_phys[setup->leg.lower_dof];
    if (p->leg_upper < 0 || (setup->leg.lower_dof >= 0 && p->leg_lower < 0))
        return rths_error_set(err, RTHS_EINPUT, "the bilinear leg must join physical DoFs");
    p->leg_k = setup->leg.stiffness_n_per_m;
    p->leg_ratio = setup->leg.ratio;
    p->leg_extra_k = (setup->leg.ratio - 1) * setup->leg.stiffness_n_per_m;
    return RTHS_OK;
}

int rths_plant_create(const rths_setup *setup, const rths_plant_options *opt, double sample_rate_hz,
                      rths_plant **out, rths_error *err) {
    *out = NULL;
    const rths_split *s = &setup->split;
    int n = s->np;
    /* the plant's own arrays have any size; the sensor sample it fills is the fixed one */
    if (n > RTHS_MAX_SENSED_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "the physical substructure has %d DoFs; a sensor sample "
                              "(rths_sensor_sample) carries at most %d displacements",
                              n, RTHS_MAX_SENSED_DOFS);
    if (s->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT, "the virtual plant has one interface DoF");
    if (!(sample_rate_hz > 0 && isfinite(sample_rate_hz)) || !(opt->gain_n_per_v > 0) ||
        !(opt->delay_s >= 0 && opt->delay_s * sample_rate_hz < 1e7) || opt->lag_cutoff_hz < 0 ||
        opt->armature_mass_kg < 0 || opt->substeps_per_sample < 0)
        return rths_error_set(err, RTHS_EINPUT, "invalid shaker options");
    int delay = (int)lround(opt->delay_s * sample_rate_hz);
    rths_plant *p = calloc(1, sizeof *p);
    if (!p) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    p->opt = *opt;
    p->n = n;
    p->h = 1.0 / sample_rate_hz;
    p->delay_samples = delay;
    p->lag_rate = opt->lag_cutoff_hz > 0 ? 2 * M_PI * opt->lag_cutoff_hz : 0;
    p->armature_kg = opt->armature_mass_kg;
    int *to_phys = NULL;
    int rc = plant_alloc(p, n, delay) || !(to_phys = physical_index(setup))
                 ? rths_error_set(err, RTHS_EFAIL, "out of memory")
                 : RTHS_OK;
    if (!rc && plant_matrices(p, setup))
        rc = rths_error_set(err, RTHS_EFAIL, "singular physical mass matrix");
    if (!rc) rc = plant_leg_and_loads(p, setup, to_phys, err);
    free(to_phys);
    double *kk = rc ? NULL : rths_mat_new(n, n);
    for (int side = 0; side < 2 && !rc; side++)
        if (!kk || build_side(p, side, kk))
            rc = rths_error_set(err, RTHS_EFAIL, "could not discretise the plant");
    rths_mat_free(kk);
    if (!rc && static_start(p)) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (rc) {
        rths_plant_destroy(p);
        return rc;
    }
    rths_rng_seed(&p->rng, opt->seed);
    *out = p;
    return RTHS_OK;
}

double rths_plant_leg_force_n(const rths_plant *p, double delta) {
    double k = p->leg_upper >= 0 ? p->leg_k : 0;
    return delta >= 0 ? k * delta : p->leg_ratio * k * delta;
}

/* forcing on the physical DoF at tau into the current sample */
static double forcing_at(const rths_plant *p, double tau) {
    return p->forcing_index < 0 || p->forcing_amplitude == 0
               ? 0.0
               : p->forcing_amplitude * cos(p->forcing_theta + p->forcing_omega * tau);
}

void rths_plant_set_forcing(rths_plant *p, double amplitude_n, double theta, double omega_rad_s) {
    p->forcing_amplitude = amplitude_n;
    p->forcing_theta = theta;
    p->forcing_omega = omega_rad_s;
}

static double leg_extension(const rths_plant *p, const double *q) {
    return p->leg_upper >= 0 ? q[p->leg_upper] - (p->leg_lower >= 0 ? q[p->leg_lower] : 0) : 0;
}

/* accelerations for state (q, v) with shaker force fs and external forcing fe; side -1 takes the
 * leg's side from q, 0 / 1 holds it at extension / compression */
static void accelerations(const rths_plant *p, const double *q, const double *v, double fs,
                          double fe, int side, double *a) {
    int n = p->n;
    double *f = p->rk + 10 * (size_t)n; /* scratch beside the ten stage arrays */
    for (int i = 0; i < n; i++) {
        double s = p->static_force[i];
        for (int j = 0; j < n; j++)
            s -= p->c[i + j * n] * v[j] + p->k[i + j * n] * q[j];
        f[i] = s;
    }
    f[n - 1] += fs;
    if (p->forcing_index >= 0) f[p->forcing_index] += fe;
    if (p->leg_upper >= 0) {
        double delta = leg_extension(p, q);
        if (side == 1 || (side < 0 && delta < 0)) {
            /* the extension stiffness is in K; compression adds the rest */
            double extra = p->leg_extra_k * delta;
            f[p->leg_upper] -= extra;
            if (p->leg_lower >= 0) f[p->leg_lower] += extra;
        }
    }
    for (int i = 0; i < n; i++) {
        double s = 0;
        for (int j = 0; j < n; j++)
            s += p->minv[i + j * n] * f[j];
        a[i] = s;
    }
}

/* The interface row of accelerations() at the current state: the only one a sensor reads. */
static double interface_acceleration(const rths_plant *p) {
    int n = p->n;
    double delta = leg_extension(p, p->q);
    double extra = p->leg_upper >= 0 && delta < 0 ? p->leg_extra_k * delta : 0.0;
    double acc = 0;
    for (int i = 0; i < n; i++) {
        double f = p->static_force[i];
        for (int j = 0; j < n; j++)
            f -= p->c[i + j * n] * p->v[j] + p->k[i + j * n] * p->q[j];
        if (i == n - 1) f += p->fs;
        if (i == p->forcing_index) f += p->forcing_now;
        if (i == p->leg_upper) f -= extra;
        if (i == p->leg_lower) f += extra;
        acc += p->minv[(n - 1) + i * n] * f;
    }
    return acc;
}

static double measure(rths_plant *p, const rths_sensor_spec *spec, double value) {
    if (!p->opt.noise) return value;
    double r =
        (1 + spec->gain_error) * value + spec->offset + spec->noise_std * rths_rng_normal(&p->rng);
    if (spec->quantum > 0) r = spec->quantum * nearbyint(r / spec->quantum);
    return r;
}

void rths_plant_read(rths_plant *p, rths_sensor_sample *out) {
    double acc = interface_acceleration(p);
    out->n = p->n;
    for (int i = 0; i < p->n; i++)
        out->displacement_m[i] = measure(p, &p->opt.laser, p->q[i]);
    out->interface_acceleration_m_s2 = measure(p, &p->opt.accelerometer, acc);
    /* the load cell sits between the armature and the storey */
    out->interface_force_n = measure(p, &p->opt.load_cell, p->fs - p->armature_kg * acc);
}

/* Classical RK4 on (q, v, fs) from tau0 to tau1 inside the sample in m substeps, the force
 * target ramping from target_start (tau = 0) to target_end (tau = h); side as in
 * accelerations. */
static void rk4_span(rths_plant *p, double tau0, double tau1, int m, double target_start,
                     double target_end, int side) {
    int n = p->n;
    double dt = (tau1 - tau0) / m;
    double *q1 = p->rk, *v1 = q1 + n, *a1 = v1 + n, *q2 = a1 + n, *v2 = q2 + n, *a2 = v2 + n,
           *q3 = a2 + n, *v3 = q3 + n, *a3 = v3 + n, *a4 = a3 + n;
    for (int s = 0; s < m; s++) {
        double t0 = (tau0 + s * dt) / p->h, t1 = (tau0 + (s + 1) * dt) / p->h;
        double target_0 = target_start + (target_end - target_start) * t0;
        double target_h = target_start + (target_end - target_start) * 0.5 * (t0 + t1);
        double target_1 = target_start + (target_end - target_start) * t1;
        double f1, f2, f3, g1, g2, g3, g4;
        if (p->lag_rate > 0) {
            g1 = p->lag_rate * (target_0 - p->fs);
        } else {
            p->fs = target_0;
            g1 = 0;
        }
        f1 = p->fs;
        double e1 = forcing_at(p, t0 * p->h), e2 = forcing_at(p, 0.5 * (t0 + t1) * p->h),
               e3 = forcing_at(p, t1 * p->h);
        accelerations(p, p->q, p->v, f1, e1, side, a1);
        f2 = p->lag_rate > 0 ? f1 + 0.5 * dt * g1 : target_h;
        g2 = p->lag_rate > 0 ? p->lag_rate * (target_h - f2) : 0;
        for (int i = 0; i < n; i++) {
            q1[i] = p->q[i] + 0.5 * dt * p->v[i];
            v1[i] = p->v[i] + 0.5 * dt * a1[i];
        }
        accelerations(p, q1, v1, f2, e2, side, a2);
        f3 = p->lag_rate > 0 ? f1 + 0.5 * dt * g2 : target_h;
        g3 = p->lag_rate > 0 ? p->lag_rate * (target_h - f3) : 0;
        for (int i = 0; i < n; i++) {
            q2[i] = p->q[i] + 0.5 * dt * v1[i];
            v2[i] = p->v[i] + 0.5 * dt * a2[i];
        }
        accelerations(p, q2, v2, f3, e2, side, a3);
        double f4 = p->lag_rate > 0 ? f1 + dt * g3 : target_1;
        g4 = p->lag_rate > 0 ? p->lag_rate * (target_1 - f4) : 0;
        for (int i = 0; i < n; i++) {
            q3[i] = p->q[i] + dt * v2[i];
            v3[i] = p->v[i] + dt * a3[i];
        }
        accelerations(p, q3, v3, f4, e3, side, a4);
        for (int i = 0; i < n; i++) {
            p->q[i] += dt / 6 * (p->v[i] + 2 * v1[i] + 2 * v2[i] + v3[i]);
            p->v[i] += dt / 6 * (a1[i] + 2 * a2[i] + 2 * a3[i] + a4[i]);
        }
        if (p->lag_rate > 0)
            p->fs += dt / 6 * (g1 + 2 * g2 + 2 * g3 + g4);
        else
            p->fs = target_1;
    }
}

/* z_next = phi z + inputs over one whole sample on one side (see exact_side). */
static void exact_step(rths_plant *p, int side, double target_start, double target_end) {
    exact_side *sd = &p->side[side];
    int nz = p->nz;
    if (p->lag_rate > 0) p->z[2 * p->n] = p->fs;
    double dt_target = target_end - target_start, fc = 0, fsn = 0;
    if (p->forcing_index >= 0 && p->forcing_amplitude != 0) {
        if (sd->forcing_omega != p->forcing_omega) build_forcing(p, side, p->forcing_omega);
        fc = p->forcing_amplitude * cos(p->forcing_theta);
        fsn = p->forcing_amplitude * sin(p->forcing_theta);
    }
    for (int i = 0; i < nz; i++) {
        double acc = sd->g_target_start[i] * target_start + sd->g_target_slope[i] * dt_target +
                     sd->g_static[i];
        if (fc != 0 || fsn != 0) acc += sd->g_forcing_cos[i] * fc + sd->g_forcing_sin[i] * fsn;
        const double *row = sd->phi + (size_t)i * nz;
        for (int j = 0; j < nz; j++)
            acc += row[j] * p->z[j];
        p->z_next[i] = acc;
    }
}

/* The leg's extension crosses zero inside the sample: the crossing time from the cubic Hermite
 * interpolant of the extension (values and rates at both ends of the unswitched step, error
 * O(h^4)), then Runge-Kutta on each side of it with the kink at a substep boundary, so neither
 * segment straddles the jump in stiffness. */
static void crossing_step(rths_plant *p, int side, double target_start, double target_end) {
    int n = p->n;
    double d0 = leg_extension(p, p->z), d1 = leg_extension(p, p->z_next);
    double r0 = leg_extension(p, p->z + n) * p->h, r1 = leg_extension(p, p->z_next + n) * p->h;
    double lo = 0, hi = 1;
    for (int it = 0; it < 60; it++) {
        double s = 0.5 * (lo + hi), s2 = s * s, s3 = s2 * s;
        double d = (2 * s3 - 3 * s2 + 1) * d0 + (s3 - 2 * s2 + s) * r0 + (-2 * s3 + 3 * s2) * d1 +
                   (s3 - s2) * r1;
        if ((d < 0) == (d0 < 0))
            lo = s;
        else
            hi = s;
    }
    double tau = 0.5 * (lo + hi) * p->h;
    if (tau > 0) rk4_span(p, 0, tau, CROSSING_SUBSTEPS, target_start, target_end, side);
    if (tau < p->h) rk4_span(p, tau, p->h, CROSSING_SUBSTEPS, target_start, target_end, !side);
}

/* rig.noise: lab, the follow-up's laboratory (opt->noise = 2): sensors ten times noisier than the
 * default rig's, and a random force on the physical interface, held per sample (amplifier noise
 * and the disturbances no sensor sees), so that a new point's first residual is only a few times
 * the tolerance. The sensors' own keys still override these levels. */
enum { PLANT_NOISE_LAB = 2 };
static const double LAB_PROCESS_FORCE_STD_N = 0.05;

static double process_force_n(rths_plant *p) {
    return p->opt.noise == PLANT_NOISE_LAB ? LAB_PROCESS_FORCE_STD_N * rths_rng_normal(&p->rng)
                                           : 0.0;
}

void rths_plant_advance(rths_plant *p, double demand_v) {
    /* transport delay in whole samples, then the amplifier-shaker lag */
    double u = demand_v;
    if (p->delay_samples > 0) {
        int len = p->delay_samples;
        u = p->delay_line[p->delay_pos];
        p->delay_line[p->delay_pos] = demand_v;
        p->delay_pos = (p->delay_pos + 1) % len;
    }
    double target_end = p->opt.gain_n_per_v * u + process_force_n(p);
    double target_start = p->opt.linear_hold ? p->last_force_target : target_end;
    p->last_force_target = target_end;
    if (p->opt.substeps_per_sample > 0) {
        rk4_span(p, 0, p->h, p->opt.substeps_per_sample, target_start, target_end, -1);
    } else {
        int side = p->leg_upper >= 0 && leg_extension(p, p->z) < 0;
        exact_step(p, side, target_start, target_end);
        int side_end = p->leg_upper >= 0 && leg_extension(p, p->z_next) < 0;
        if (side_end != side) {
            crossing_step(p, side, target_start, target_end);
        } else {
            memcpy(p->z, p->z_next, sizeof(double) * (size_t)p->nz);
            p->fs = p->lag_rate > 0 ? p->z[2 * p->n] : target_end;
        }
    }
    p->forcing_now = forcing_at(p, p->h);
    p->time_s += p->h;
}

double rths_plant_time_s(const rths_plant *p) {
    return p->time_s;
}
double rths_plant_interface_displacement_m(const rths_plant *p) {
    return p->q[p->n - 1];
}
double rths_plant_noise_level_m(const rths_plant *p) {
    return p->opt.noise ? p->opt.laser.noise_std : 0.0;
}

static int read_noise(rths_config *cfg, rths_plant_options *opt, rths_error *err) {
    const char *text = NULL;
    int rc = rths_config_get_string(cfg, "rig.noise", 0, NULL, &text, err);
    if (rc || !text) return rc;
    if (strcmp(text, "lab")) {
        rths_error bool_err;
        if (rths_config_get_bool(cfg, "rig.noise", 0, opt->noise, &opt->noise, &bool_err))
            return rths_config_error_at(cfg, "rig.noise", err,
                                        "expected true, false or lab, got '%s'", text);
        return RTHS_OK;
    }
    opt->noise = PLANT_NOISE_LAB;
    opt->laser.noise_std = 1e-6;
    opt->accelerometer.noise_std = 0.1;
    opt->load_cell.noise_std = 0.1;
    return RTHS_OK;
}

int rths_plant_config_read(rths_config *cfg, rths_plant_options *opt, rths_error *err) {
    /* substeps_per_sample 0 is the exact integrator; rk4 takes 8 substeps unless told */
    long seed = (long)opt->seed,
         substeps = opt->substeps_per_sample > 0 ? opt->substeps_per_sample : 8;
    static const char *const holds[] = {"linear", "step", NULL};
    static const char *const integrators[] = {"exact", "rk4", NULL};
    int hold = 0, integrator = 0;
    int rc;
    if ((rc = read_noise(cfg, opt, err)) ||
        (rc = rths_config_get_int(cfg, "rig.seed", 0, seed, 0, 2147483647L, &seed, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.plant_integrator", 0,
                                     opt->substeps_per_sample > 0 ? 1 : 0, integrators, &integrator,
                                     err)) ||
        (rc = rths_config_get_int(cfg, "rig.substeps_per_sample", 0, substeps, 1, 1000, &substeps,
                                  err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.gain_n_per_v", 0, opt->gain_n_per_v, 1e-6,
                                     1e6, &opt->gain_n_per_v, err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.delay_s", 0, opt->delay_s, 0, 0.1,
                                     &opt->delay_s, err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.lag_cutoff_hz", 0, opt->lag_cutoff_hz, 0, 1e6,
                                     &opt->lag_cutoff_hz, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.shaker.hold", 0, opt->linear_hold ? 0 : 1, holds,
                                     &hold, err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.armature_mass_kg", 0, opt->armature_mass_kg,
                                     0, 1e3, &opt->armature_mass_kg, err)))
        return rc;
    opt->seed = (uint64_t)seed;
    if (integrator == 0 && rths_config_has(cfg, "rig.substeps_per_sample"))
        return rths_config_error_at(cfg, "rig.substeps_per_sample", err,
                                    "applies to rig.plant_integrator: rk4 only (the exact "
                                    "integrator has no substeps)");
    opt->substeps_per_sample = integrator == 1 ? (int)substeps : 0;
    opt->linear_hold = hold == 0;
    struct {
        const char *name;
        rths_sensor_spec *spec;
    } sensors[3] = {{"laser", &opt->laser},
                    {"accelerometer", &opt->accelerometer},
                    {"load_cell", &opt->load_cell}};
    static const char *const fields[4] = {"gain_error", "offset", "noise_std", "quantum"};
    for (int s = 0; s < 3; s++) {
        double *values[4] = {&sensors[s].spec->gain_error, &sensors[s].spec->offset,
                             &sensors[s].spec->noise_std, &sensors[s].spec->quantum};
        for (int f = 0; f < 4; f++) {
            char key[96];
            snprintf(key, sizeof key, "rig.sensors.%s.%s", sensors[s].name, fields[f]);
            double lo = f == 0 ? -0.5 : f == 1 ? -1e6 : 0, hi = f == 0 ? 0.5 : 1e6;
            if ((rc = rths_config_get_double(cfg, key, 0, *values[f], lo, hi, values[f], err)))
                return rc;
        }
    }
    return RTHS_OK;
}
