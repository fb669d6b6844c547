/* The virtual laboratory: physical substructure, bilinear leg, shaker, sensors (see plant.h).
 *
 * This file: the per-sample path (compiled with the per-sample options of CMakeLists.txt): the
 * forcing, the sensors read, each actuator's command through its DAC, delay and hold, the
 * structure advanced over a sample (exact discretisation, the leg's kink located, or RK4) and
 * the limits checked. Building a plant is in plant_build.c, reading its options in
 * plant_config.c (plant_internal.h). */
#include "plant/plant_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
    f[n - p->ni] += fs; /* one actuator only on this path (rths_plant_create) */
    if (p->forcing_shape)
        for (int i = 0; i < n; i++)
            f[i] += fe * p->forcing_shape[i];
    else if (p->forcing_index >= 0)
        f[p->forcing_index] += fe;
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

/* Every interface DoF's acceleration in the current state, m/s^2 (rad/s^2 for a rotation). */
static void interface_accelerations(const rths_plant *p, double *acc) {
    int n = p->n, ni = p->ni, len = p->accel_row_len;
    double delta = leg_extension(p, p->q);
    double extra = p->leg_upper >= 0 && delta < 0 ? p->leg_extra_k * delta : 0.0;
    for (int d = 0; d < ni; d++) {
        const double *r = p->accel_rows + (size_t)(d * len);
        double a = r[2 * n + ni] + r[2 * n + ni + 1] * p->forcing_now + r[2 * n + ni + 2] * extra +
                   r[2 * n] * p->fs;
        for (int e = 1; e < ni; e++)
            a += r[2 * n + e] * p->fs_more[e];
        for (int j = 0; j < 2 * n; j++) /* q, then v: z's first 2n */
            a += r[j] * p->z[j];
        acc[d] = a;
    }
}

/* value clipped to +-range and rounded to the step 2 range / 2^bits (bits 0: unchanged) */
/* nearbyint in the default rounding mode (to nearest, ties to even), inline: adding 1.5 x 2^52
 * leaves no fraction bits for |x| < 2^51, so the sum rounds x to an integer (a zero comes out
 * +0). Per-sample sensors called the libm function several times a sample. */
static double round_to_integer(double x) {
    const double shift = 6755399441055744.0;                       /* 1.5 x 2^52 */
    return fabs(x) < 2251799813685248.0 ? (x + shift) - shift : x; /* |x| < 2^51 */
}

/* value clipped to +-range (NaN to -range, as fmin(fmax(...)) does) and rounded to the step
 * 2 range / 2^bits (bits 0: unchanged) */
static double convert(int bits, double range, double value) {
    if (bits <= 0) return value;
    double q = 2 * range / (double)(1ULL << (bits < 63 ? bits : 63)); /* exact power of two */
    double clipped = value > -range ? value : -range;
    clipped = clipped < range ? clipped : range;
    return q * round_to_integer(clipped / q);
}

/* the plant's next standard normal draw */
static inline double normal_draw(rths_plant *p) {
    if (p->normal_next == NORMAL_POOL) {
        rths_rng_normals(&p->rng, p->normal_pool, NORMAL_POOL);
        p->normal_next = 0;
    }
    return p->normal_pool[p->normal_next++];
}

static inline double measure(rths_plant *p, const sensor_channel *ch, double value) {
    double r = value;
    if (ch->noisy) {
        r = ch->gain * value + ch->offset + ch->noise_std * normal_draw(p);
        if (ch->quantum > 0) r = ch->quantum * round_to_integer(r * ch->per_quantum);
    }
    if (!ch->converter) return r;
    /* through the converter, in volts */
    double v = r * ch->per_unit_v;
    if (ch->adc_noise_v > 0) v += ch->adc_noise_v * normal_draw(p);
    return convert(ch->adc_bits, ch->adc_range_v, v) * ch->units_per_v;
}

/* Each laser reads its point (S q, or the DoF itself without a laser transform), each
 * actuator's accelerometer and load cell sit at the actuator's point, whose acceleration is
 * T^T q'' (the DoF's own without an actuator transform). Draws the noise in the same order
 * with and without transforms: the DoFs below the interface, the interface lasers, then per
 * actuator its accelerometer and load cell. */
void rths_plant_read(rths_plant *p, rths_sensor_sample *out) {
    int n = p->n, ni = p->ni, iface = n - ni;
    double acc[RTHS_MAX_INTERFACE_DOFS];
    interface_accelerations(p, acc);
    out->n = n;
    for (int i = 0; i < iface; i++)
        out->displacement_m[i] = measure(p, &p->sensor[SENSOR_LASER], p->q[i]);
    for (int l = 0; l < ni; l++) {
        double y = p->q[iface + l];
        if (p->sens_t) {
            y = 0;
            for (int d = 0; d < ni; d++)
                y += p->sens_t[l + d * ni] * p->q[iface + d];
        }
        out->displacement_m[iface + l] = measure(p, &p->sensor[SENSOR_LASER], y);
    }
    out->n_interface = ni;
    for (int a = 0; a < ni; a++) {
        double acc_a = acc[a];
        if (p->act_t) {
            acc_a = 0;
            for (int d = 0; d < ni; d++)
                acc_a += p->act_t[d + a * ni] * acc[d];
        }
        double actuator_force = a == 0 ? p->fs : p->fs_more[a];
        out->interface_acceleration_dof_m_s2[a] =
            measure(p, &p->sensor[SENSOR_ACCELEROMETER], acc_a);
        /* the load cell sits between the armature and the structure */
        out->interface_force_dof_n[a] =
            measure(p, &p->sensor[SENSOR_LOAD_CELL], actuator_force - p->armature_kg * acc_a);
    }
    out->interface_acceleration_m_s2 = out->interface_acceleration_dof_m_s2[0];
    out->interface_force_n = out->interface_force_dof_n[0];
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
static void exact_step(rths_plant *p, int side, double target_start, double target_end,
                       const double *more_start, const double *more_end) {
    exact_side *sd = &p->side[side];
    int nz = p->nz;
    if (p->lag_rate > 0) p->z[2 * p->n] = p->fs;
    for (int d = 1; p->lag_rate > 0 && d < p->ni; d++)
        p->z[2 * p->n + d] = p->fs_more[d];
    double dt_target = target_end - target_start, f[4] = {0, 0, 0, 0};
    int forced = p->forcing_index >= 0 && p->forcing_amplitude != 0;
    if (forced) { /* amplitude cos(theta + omega tau) and its first three derivatives at 0 */
        double w = p->forcing_omega, c = p->forcing_amplitude * cos(p->forcing_theta),
               sn = p->forcing_amplitude * sin(p->forcing_theta);
        f[0] = c, f[1] = -w * sn, f[2] = -w * w * c, f[3] = w * w * w * sn;
    }
    for (int i = 0; i < nz; i++) {
        double acc = sd->g_target_start[i] * target_start + sd->g_target_slope[i] * dt_target +
                     sd->g_static[i];
        if (forced)
            acc += sd->g_forcing[0][i] * f[0] + sd->g_forcing[1][i] * f[1] +
                   sd->g_forcing[2][i] * f[2] + sd->g_forcing[3][i] * f[3];
        for (int d = 1; d < p->ni; d++) {
            const double *g = sd->g_more + (size_t)(2 * (d - 1)) * nz;
            acc += g[i] * more_start[d] + g[i + nz] * (more_end[d] - more_start[d]);
        }
        /* four terms a pass over the padded row: the same sum in the same order (the padding
         * adds zeros), without a loop's overhead per term at the seed's size (nz = 7) */
        const double *row = sd->phi + (size_t)i * (size_t)p->nz_padded, *z = p->z;
        for (int j = 0; j < p->nz_padded; j += 4) {
            acc += row[j] * z[j];
            acc += row[j + 1] * z[j + 1];
            acc += row[j + 2] * z[j + 2];
            acc += row[j + 3] * z[j + 3];
        }
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

/* fmax for the per-sample limits, inline (a NaN gives the other operand; signed zeros do not
 * matter here): the libm call cost three or more calls per sample */
static double larger(double a, double b) {
    return b > a || a != a ? b : a;
}

/* After each sample: peaks, flagged samples, and the limit (action fault) the state is beyond. */
static void limits_update(rths_plant *p) {
    const rths_actuator_options *a = &p->opt.actuator;
    rths_actuator_status *st = &p->status;
    int iface = p->n - p->ni;
    double x = fabs(p->q[iface]), v = fabs(p->v[iface]), f = fabs(p->fs);
    for (int d = 1; d < p->ni; d++) {
        x = larger(x, fabs(p->q[iface + d]));
        v = larger(v, fabs(p->v[iface + d]));
        f = larger(f, fabs(p->fs_more[d]));
    }
    if (p->act_t) { /* stroke and velocity of each actuator's own point, T^T q */
        x = v = 0;
        for (int a = 0; a < p->ni; a++) {
            double xa = 0, va = 0;
            for (int d = 0; d < p->ni; d++) {
                xa += p->act_t[d + a * p->ni] * p->q[iface + d];
                va += p->act_t[d + a * p->ni] * p->v[iface + d];
            }
            x = larger(x, fabs(xa));
            v = larger(v, fabs(va));
        }
    }
    st->peak_stroke_m = larger(st->peak_stroke_m, x);
    st->peak_velocity_m_per_s = larger(st->peak_velocity_m_per_s, v);
    st->peak_force_n = larger(st->peak_force_n, f);
    st->beyond = RTHS_RIG_OK;
    if (a->stroke_limit_m > 0 && x > a->stroke_limit_m) {
        if (a->stroke_flag)
            st->stroke_flagged_samples++;
        else
            st->beyond = RTHS_RIG_FAULT_DISPLACEMENT;
    }
    if (a->velocity_limit_m_per_s > 0 && v > a->velocity_limit_m_per_s) {
        if (a->velocity_flag)
            st->velocity_flagged_samples++;
        else
            st->beyond = RTHS_RIG_FAULT_DISPLACEMENT;
    }
    if (a->force_limit_n > 0 && !a->force_clip && f > a->force_limit_n)
        st->beyond = RTHS_RIG_FAULT_FORCE;
}

rths_rig_fault rths_plant_limit_fault(const rths_plant *p) {
    return p->status.beyond;
}

void rths_plant_actuator_status(const rths_plant *p, rths_actuator_status *out) {
    *out = p->status;
}

/* rig.noise: lab (PLANT_NOISE_LAB, plant_internal.h): the random force on the physical interface */
static const double LAB_PROCESS_FORCE_STD_N = 0.05;

static double process_force_n(rths_plant *p) {
    return p->opt.noise == PLANT_NOISE_LAB ? LAB_PROCESS_FORCE_STD_N * normal_draw(p) : 0.0;
}

/* Actuator d's force command at the end of this sample from its demand: the DAC, the transport
 * delay in whole samples (its own line; the caller advances the shared position), the gain or
 * the transfer function's input, the clip and the lab's process force. */
static double actuator_command(rths_plant *p, int d, double demand_v) {
    double u = convert(p->opt.actuator.dac_bits, p->opt.actuator.dac_range_v, demand_v);
    if (p->delay_samples > 0) {
        double *line = p->delay_line + (size_t)d * (size_t)(p->delay_samples + 1);
        double converted = u; /* the DAC's output is what travels down the delay */
        u = line[p->delay_pos];
        line[p->delay_pos] = converted;
    }
    /* the actuator's input: the force command (shaker) or the demand (transfer function) */
    double target_end = p->tf ? u : p->opt.gain_n_per_v * u;
    if (p->command_limit > 0 && fabs(target_end) > p->command_limit) {
        target_end = copysign(p->command_limit, target_end);
        p->status.force_clipped_samples++;
    }
    /* rig.noise: lab: a random force on the interface beside the shaker's (0 otherwise, no draw) */
    if (!p->tf) target_end += process_force_n(p);
    return target_end;
}

void rths_plant_advance(rths_plant *p, double demand_v) {
    rths_plant_advance_dofs(p, &demand_v);
}

void rths_plant_advance_dofs(rths_plant *p, const double *demand_v) {
    double target_end = actuator_command(p, 0, demand_v[0]);
    double more_start[RTHS_MAX_INTERFACE_DOFS] = {0}, more_end[RTHS_MAX_INTERFACE_DOFS] = {0};
    for (int d = 1; d < p->ni; d++) {
        more_end[d] = actuator_command(p, d, demand_v[d]);
        more_start[d] = p->opt.linear_hold ? p->last_force_target_more[d] : more_end[d];
        p->last_force_target_more[d] = more_end[d];
    }
    if (p->delay_samples > 0 && ++p->delay_pos == p->delay_samples) p->delay_pos = 0;
    double target_start = p->opt.linear_hold ? p->last_force_target : target_end;
    p->last_force_target = target_end;
    if (p->opt.substeps_per_sample > 0) {
        rk4_span(p, 0, p->h, p->opt.substeps_per_sample, target_start, target_end, -1);
    } else {
        int side = p->leg_upper >= 0 && leg_extension(p, p->z) < 0;
        exact_step(p, side, target_start, target_end, more_start, more_end);
        int side_end = p->leg_upper >= 0 && leg_extension(p, p->z_next) < 0;
        if (side_end != side) {
            crossing_step(p, side, target_start, target_end);
        } else {
            for (int i = 0; i < p->nz; i++) /* a handful of doubles: cheaper than a libc call */
                p->z[i] = p->z_next[i];
            if (p->tf)
                p->fs = p->act_out * ((p->na > 0 ? p->z[2 * p->n + p->na - 1] : 0.0) +
                                      p->act_d * target_end) -
                        p->act_spring * p->q[p->n - 1];
            else
                p->fs = p->lag_rate > 0 ? p->z[2 * p->n] : target_end;
            for (int d = 1; d < p->ni; d++)
                p->fs_more[d] = p->lag_rate > 0 ? p->z[2 * p->n + d] : more_end[d];
        }
    }
    p->forcing_now = forcing_at(p, p->h);
    p->time_s += p->h;
    limits_update(p);
}

double rths_plant_time_s(const rths_plant *p) {
    return p->time_s;
}
double rths_plant_interface_displacement_m(const rths_plant *p) {
    return p->q[p->n - p->ni];
}
double rths_plant_noise_level_m(const rths_plant *p) {
    if (!p->opt.noise) return 0.0;
    if (!p->sens_t) return p->opt.laser.noise_std;
    /* through the lasers' transform the controller's interface DoFs read S^-1 y: DoF d's noise is
     * the laser noise times the norm of row d of S^-1 (the largest is reported) */
    int ni = p->ni;
    double inv[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_INTERFACE_DOFS], gain = 0;
    if (rths_mat_inverse(ni, p->sens_t, inv)) return p->opt.laser.noise_std;
    for (int d = 0; d < ni; d++) {
        double row = 0;
        for (int l = 0; l < ni; l++)
            row += inv[d + l * ni] * inv[d + l * ni];
        gain = fmax(gain, sqrt(row));
    }
    return gain * p->opt.laser.noise_std;
}
