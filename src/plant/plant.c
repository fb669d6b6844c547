/* The virtual laboratory: physical substructure, bilinear leg, shaker, sensors (see plant.h). */
#include "rths/plant.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAXN RTHS_MAX_SENSED_DOFS
#define MAX_DELAY 4096

struct rths_plant {
    rths_plant_options opt;
    int n; /* physical DoFs, interface last */
    double h, dt;
    double minv[MAXN * MAXN], c[MAXN * MAXN], k[MAXN * MAXN];
    double static_force[MAXN];
    int leg_lower, leg_upper; /* physical indices (-1: ground), leg_upper < 0: no bilinear leg */
    double leg_extra_k;       /* (ratio - 1) k added in compression */
    double leg_k, leg_ratio;
    double q[MAXN], v[MAXN], fs; /* state: displacement, velocity, shaker force */
    double time_s;
    double delay_line[MAX_DELAY];
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
    opt->substeps_per_sample = 8;
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

int rths_plant_create(const rths_setup *setup, const rths_plant_options *opt, double sample_rate_hz,
                      rths_plant **out, rths_error *err) {
    *out = NULL;
    const rths_split *s = &setup->split;
    int n = s->np;
    if (n > MAXN) return rths_error_set(err, RTHS_EINPUT, "at most %d physical DoFs", MAXN);
    if (s->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT, "the virtual plant has one interface DoF");
    if (!(opt->gain_n_per_v > 0) || opt->delay_s < 0 || opt->lag_cutoff_hz < 0 ||
        opt->armature_mass_kg < 0 || opt->substeps_per_sample < 1)
        return rths_error_set(err, RTHS_EINPUT, "invalid shaker options");
    int delay = (int)lround(opt->delay_s * sample_rate_hz);
    if (delay >= MAX_DELAY)
        return rths_error_set(err, RTHS_EINPUT, "shaker delay %g s is too long", opt->delay_s);
    rths_plant *p = calloc(1, sizeof *p);
    if (!p) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    p->opt = *opt;
    p->n = n;
    p->h = 1.0 / sample_rate_hz;
    p->dt = p->h / opt->substeps_per_sample;
    p->delay_samples = delay;
    p->lag_rate = opt->lag_cutoff_hz > 0 ? 2 * M_PI * opt->lag_cutoff_hz : 0;
    p->armature_kg = opt->armature_mass_kg;
    /* the rig's interface storey carries the assembly's full interface mass plus the armature */
    double m[MAXN * MAXN];
    int iface = s->int_dofs[0];
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            m[i + j * n] = RTHS_AT(s->mass_phys, n, i, j);
            p->c[i + j * n] = RTHS_AT(s->damping_phys, n, i, j);
            p->k[i + j * n] = RTHS_AT(s->stiffness_phys, n, i, j);
        }
    m[(n - 1) + (n - 1) * n] =
        RTHS_AT(setup->assembly.mass, setup->assembly.n, iface, iface) + opt->armature_mass_kg;
    if (rths_mat_inverse(n, m, p->minv)) {
        free(p);
        return rths_error_set(err, RTHS_EFAIL, "singular physical mass matrix");
    }
    /* physical order: internal physical DoFs, then the interface */
    int to_phys[256];
    for (int i = 0; i < setup->assembly.n && i < 256; i++)
        to_phys[i] = -1;
    for (int i = 0; i < s->n_phys; i++)
        to_phys[s->phys_dofs[i]] = i;
    to_phys[iface] = n - 1;
    for (int i = 0; i < setup->assembly.n; i++)
        if (to_phys[i] >= 0 && setup->static_force)
            p->static_force[to_phys[i]] = setup->static_force[i];
    p->forcing_index = -1;
    for (int i = 0; i < s->n_phys; i++)
        if (s->phys_dofs[i] == setup->forcing_dof) p->forcing_index = i;
    p->leg_upper = -1;
    if (setup->has_bilinear) {
        p->leg_upper = to_phys[setup->leg.upper_dof];
        p->leg_lower = setup->leg.lower_dof < 0 ? -1 : to_phys[setup->leg.lower_dof];
        if (p->leg_upper < 0 || (setup->leg.lower_dof >= 0 && p->leg_lower < 0)) {
            free(p);
            return rths_error_set(err, RTHS_EINPUT, "the bilinear leg must join physical DoFs");
        }
        p->leg_k = setup->leg.stiffness_n_per_m;
        p->leg_ratio = setup->leg.ratio;
        p->leg_extra_k = (setup->leg.ratio - 1) * setup->leg.stiffness_n_per_m;
    }
    rths_rng_seed(&p->rng, opt->seed);
    /* start at rest in static equilibrium under the preload: K q + g(q) = f_static, solved for
     * each side of the kink and kept where the assumed side is consistent */
    double q[MAXN], kk[MAXN * MAXN];
    for (int side = 0; side < 2; side++) {
        memcpy(kk, p->k, sizeof(double) * (size_t)(n * n));
        memcpy(q, p->static_force, sizeof(double) * (size_t)n);
        if (side == 1 && p->leg_upper >= 0) {
            int a = p->leg_upper, b = p->leg_lower;
            kk[a + a * n] += p->leg_extra_k;
            if (b >= 0) {
                kk[b + b * n] += p->leg_extra_k;
                kk[a + b * n] -= p->leg_extra_k;
                kk[b + a * n] -= p->leg_extra_k;
            }
        }
        if (rths_mat_solve(n, 1, kk, q)) continue;
        double delta =
            p->leg_upper >= 0 ? q[p->leg_upper] - (p->leg_lower >= 0 ? q[p->leg_lower] : 0) : 0;
        if (p->leg_upper < 0 || (side == 0) == (delta >= 0)) {
            memcpy(p->q, q, sizeof(double) * (size_t)n);
            break;
        }
    }
    *out = p;
    return RTHS_OK;
}

void rths_plant_destroy(rths_plant *p) {
    free(p);
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

/* accelerations for state (q, v) with shaker force fs and external forcing fe */
static void accelerations(const rths_plant *p, const double *q, const double *v, double fs,
                          double fe, double *a) {
    int n = p->n;
    double f[MAXN] = {0};
    for (int i = 0; i < n; i++) {
        double s = p->static_force[i];
        for (int j = 0; j < n; j++)
            s -= p->c[i + j * n] * v[j] + p->k[i + j * n] * q[j];
        f[i] = s;
    }
    f[n - 1] += fs;
    if (p->forcing_index >= 0) f[p->forcing_index] += fe;
    if (p->leg_upper >= 0) {
        double delta = q[p->leg_upper] - (p->leg_lower >= 0 ? q[p->leg_lower] : 0);
        if (delta < 0) {
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

static double measure(rths_plant *p, const rths_sensor_spec *spec, double value) {
    if (!p->opt.noise) return value;
    double r =
        (1 + spec->gain_error) * value + spec->offset + spec->noise_std * rths_rng_normal(&p->rng);
    if (spec->quantum > 0) r = spec->quantum * nearbyint(r / spec->quantum);
    return r;
}

void rths_plant_read(rths_plant *p, rths_sensor_sample *out) {
    double a[MAXN];
    accelerations(p, p->q, p->v, p->fs, p->forcing_now, a);
    out->n = p->n;
    for (int i = 0; i < p->n; i++)
        out->displacement_m[i] = measure(p, &p->opt.laser, p->q[i]);
    double acc = a[p->n - 1];
    out->interface_acceleration_m_s2 = measure(p, &p->opt.accelerometer, acc);
    /* the load cell sits between the armature and the storey */
    out->interface_force_n = measure(p, &p->opt.load_cell, p->fs - p->armature_kg * acc);
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
    double target_end = p->opt.gain_n_per_v * u;
    double target_start = p->opt.linear_hold ? p->last_force_target : target_end;
    p->last_force_target = target_end;
    int n = p->n;
    double dt = p->dt;
    int m = p->opt.substeps_per_sample;
    for (int s = 0; s < m; s++) {
        /* classical RK4 on (q, v, fs); the force target is linear in time within the sample */
        double t0 = (double)s / m, t1 = (double)(s + 1) / m;
        double target_0 = target_start + (target_end - target_start) * t0;
        double target_h = target_start + (target_end - target_start) * 0.5 * (t0 + t1);
        double target_1 = target_start + (target_end - target_start) * t1;
        double q1[MAXN], v1[MAXN], a1[MAXN], q2[MAXN], v2[MAXN], a2[MAXN], q3[MAXN], v3[MAXN],
            a3[MAXN], a4[MAXN];
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
        accelerations(p, p->q, p->v, f1, e1, a1);
        f2 = p->lag_rate > 0 ? f1 + 0.5 * dt * g1 : target_h;
        g2 = p->lag_rate > 0 ? p->lag_rate * (target_h - f2) : 0;
        for (int i = 0; i < n; i++) {
            q1[i] = p->q[i] + 0.5 * dt * p->v[i];
            v1[i] = p->v[i] + 0.5 * dt * a1[i];
        }
        accelerations(p, q1, v1, f2, e2, a2);
        f3 = p->lag_rate > 0 ? f1 + 0.5 * dt * g2 : target_h;
        g3 = p->lag_rate > 0 ? p->lag_rate * (target_h - f3) : 0;
        for (int i = 0; i < n; i++) {
            q2[i] = p->q[i] + 0.5 * dt * v1[i];
            v2[i] = p->v[i] + 0.5 * dt * a2[i];
        }
        accelerations(p, q2, v2, f3, e2, a3);
        double f4 = p->lag_rate > 0 ? f1 + dt * g3 : target_1;
        g4 = p->lag_rate > 0 ? p->lag_rate * (target_1 - f4) : 0;
        for (int i = 0; i < n; i++) {
            q3[i] = p->q[i] + dt * v2[i];
            v3[i] = p->v[i] + dt * a3[i];
        }
        accelerations(p, q3, v3, f4, e3, a4);
        for (int i = 0; i < n; i++) {
            p->q[i] += dt / 6 * (p->v[i] + 2 * v1[i] + 2 * v2[i] + v3[i]);
            p->v[i] += dt / 6 * (a1[i] + 2 * a2[i] + 2 * a3[i] + a4[i]);
        }
        if (p->lag_rate > 0)
            p->fs += dt / 6 * (g1 + 2 * g2 + 2 * g3 + g4);
        else
            p->fs = target_1;
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

int rths_plant_config_read(rths_config *cfg, rths_plant_options *opt, rths_error *err) {
    long seed = (long)opt->seed, substeps = opt->substeps_per_sample;
    static const char *const holds[] = {"linear", "step", NULL};
    int hold = 0;
    int rc;
    if ((rc = rths_config_get_bool(cfg, "rig.noise", 0, opt->noise, &opt->noise, err)) ||
        (rc = rths_config_get_int(cfg, "rig.seed", 0, seed, 0, 2147483647L, &seed, err)) ||
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
    opt->substeps_per_sample = (int)substeps;
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
