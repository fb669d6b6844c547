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
 *         + sum_k g_forcing[k] f^(k)(0)
 * for the force target ramping from T0 to T1 (equal for a DAC step) and the forcing
 * f(tau) = amplitude cos(theta + omega tau) on the physical DoFs, through its Taylor polynomial
 * of degree 3 over the sample (derivatives exact; truncation (omega h)^4 / 24, 2e-10 at 13 Hz and
 * 10 kHz). The g_forcing are the responses to the unit powers tau^k / k!: computed once at
 * create for every frequency, so a frequency change costs the per-sample loop nothing (no
 * matrix exponential, no allocation, no LAPACK). */
typedef struct {
    double *phi; /* nz rows of nz_padded, row-major; the padding columns are zero */
    double *g_target_start, *g_target_slope, *g_static;
    double *g_forcing[4];
    /* actuators 1..ni-1 (several interface DoFs): their force targets' start and slope columns,
       nz each, actuator d's pair at 2 (d - 1) nz; NULL with one actuator */
    double *g_more;
} exact_side;

/* A sensor's options as one reading uses them, the noise switch applied and the reciprocals of
 * its step and scale formed once (a division per reading sat on the read's critical path; the
 * product differs from the quotient by an ulp at most, which moves a rounding to the step only
 * within an ulp of a half step). */
typedef struct {
    int noisy;                      /* rig.noise on: gain error, offset, noise, step apply */
    double gain, offset, noise_std; /* 1 + gain_error, offset, noise, in the sensor's unit */
    double quantum, per_quantum;    /* the step and its reciprocal (0: none) */
    int converter;                  /* an ADC's resolution or its volts noise applies */
    int adc_bits;
    double adc_range_v, units_per_v, per_unit_v, adc_noise_v; /* adc_noise_v 0 without noise */
} sensor_channel;
enum { SENSOR_LASER, SENSOR_ACCELEROMETER, SENSOR_LOAD_CELL, SENSOR_KINDS };

enum { NORMAL_POOL = 64 };

struct rths_plant {
    rths_plant_options opt;
    sensor_channel sensor[SENSOR_KINDS];
    int n;  /* physical DoFs, the interface DoFs last */
    int ni; /* interface DoFs, one actuator each: actuator d acts on physical DoF n - ni + d */
    double h;
    double *minv, *c, *k; /* n x n */
    /* the interface DoFs' accelerations as rows of M^-1 applied to the forces, per DoF d at
     * d * accel_row_len: 2n state coefficients (-M^-1 K, -M^-1 C), ni actuator forces, then the
     * static force's, the forcing's and the leg's compression force's (see accel_rows_init) */
    double *accel_rows;
    int accel_row_len;
    double *static_force;     /* n */
    int leg_lower, leg_upper; /* physical indices (-1: ground), leg_upper < 0: no bilinear leg */
    double leg_extra_k;       /* (ratio - 1) k added in compression */
    double leg_k, leg_ratio;
    double *z;         /* state: q (n), v (n), then the shaker force when it lags */
    double *q, *v, fs; /* q = z, v = z + n; shaker force */
    double *z_next;    /* nz */
    double *rk;        /* scratch: Runge-Kutta stages 10 n, forces n */
    int nz;            /* 2n + na */
    int nz_padded;     /* nz rounded up to a multiple of 4: phi's rows and z, padded with zeros,
                          are summed four terms per loop pass */
    int na;            /* actuator states: 1 for the shaker's lag, the order of a transfer
                          function (observer canonical form, after q and v in z) */
    int tf;            /* transfer-function actuator: the input is the demand itself */
    double *act_a, *act_bu, *act_bv; /* na x na (column-major), na, na */
    double act_d;                    /* feedthrough of the demand to the output */
    double act_out;       /* force per unit output: 1 (force output) or the connection stiffness */
    double act_spring;    /* displacement output: the connection's stiffness k_c, N/m; 0: force */
    double command_limit; /* force clip: |input| at most this (0: no clip) */
    rths_actuator_status status;
    exact_side side[2]; /* 0: extension (or no leg), 1: compression */
    double time_s;
    double *delay_line;
    int delay_samples, delay_pos;
    double lag_rate;          /* 2 pi f_c, 0: no lag */
    double last_force_target; /* gain x demand of the previous sample (linear hold) */
    double armature_kg;
    /* actuators 1..ni-1 (index 0 unused: actuator 0 is fs, last_force_target, delay_line) */
    double fs_more[RTHS_MAX_INTERFACE_DOFS], last_force_target_more[RTHS_MAX_INTERFACE_DOFS];
    /* actuator and sensor transforms (setup.h), ni x ni column-major; NULL: the identity */
    double *act_t, *sens_t;
    int forcing_index;     /* internal physical forcing DoF, -1: none */
    double *forcing_shape; /* n: base excitation's -M 1 on the internal physical DoFs; NULL:
                              the forcing acts on forcing_index alone */
    double forcing_amplitude, forcing_theta, forcing_omega, forcing_now;
    rths_rng rng;
    /* normal draws of rng, taken in order: refilled a block at a time, where a call per draw
     * cost as much as the draw (the sequence is the same as drawing one by one) */
    double normal_pool[NORMAL_POOL];
    int normal_next; /* next unused entry; NORMAL_POOL: empty */
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
    rths_adc_spec no_adc = {.bits = 0, .range_v = 10.0, .units_per_v = 1.0, .noise_v = 0};
    opt->laser_adc = opt->accelerometer_adc = opt->load_cell_adc = no_adc;
    opt->actuator.model = RTHS_ACTUATOR_SHAKER;
    opt->actuator.dac_range_v = 10.0;
}

const char *rths_actuator_model_name(rths_actuator_model model) {
    return model == RTHS_ACTUATOR_TRANSFER_FUNCTION ? "transfer_function" : "shaker";
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
    free(p->z), free(p->z_next), free(p->rk), free(p->delay_line), free(p->accel_rows);
    free(p->act_a), free(p->act_bu), free(p->act_bv), free(p->forcing_shape);
    rths_mat_free(p->act_t), rths_mat_free(p->sens_t);
    for (int s = 0; s < 2; s++) {
        exact_side *e = &p->side[s];
        free(e->phi), free(e->g_target_start), free(e->g_target_slope), free(e->g_static);
        for (int k = 0; k < 4; k++)
            free(e->g_forcing[k]);
        free(e->g_more);
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

/* Row i of M^-1 times actuator a's force direction: the interface DoF a itself, or through the
 * actuator transform, column a of T. */
static double actuator_input(const rths_plant *p, int i, int a) {
    int n = p->n, iface = n - p->ni;
    if (!p->act_t) return p->minv[i + (iface + a) * n];
    double s = 0;
    for (int d = 0; d < p->ni; d++)
        s += p->minv[i + (iface + d) * n] * p->act_t[d + a * p->ni];
    return s;
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
        /* actuator d's lagged force acts on interface DoF d */
        for (int d = 0; p->lag_rate > 0 && d < p->ni; d++)
            a[n + i + (size_t)(2 * n + d) * ld] = actuator_input(p, i, d);
        /* the transfer function's output is its last observer state (plus the feedthrough):
         * the force, or the piston's displacement pushing the storey through the connection
         * spring, F = k_c (y - x_interface) */
        if (p->tf && p->na > 0)
            a[n + i + (size_t)(2 * n + p->na - 1) * ld] = p->minv[i + (n - 1) * n] * p->act_out;
        if (p->tf && p->act_spring > 0)
            a[n + i + (size_t)(n - 1) * ld] -= p->minv[i + (n - 1) * n] * p->act_spring;
    }
    for (int d = 0; p->lag_rate > 0 && d < p->ni; d++)
        a[2 * n + d + (size_t)(2 * n + d) * ld] = -p->lag_rate;
    for (int i = 0; p->tf && i < p->na; i++) {
        for (int j = 0; j < p->na; j++)
            a[2 * n + i + (size_t)(2 * n + j) * ld] = p->act_a[i + j * p->na];
        a[2 * n + i + (size_t)(2 * n - 1) * ld] = p->act_bv[i]; /* interface velocity */
    }
}

/* Row i of M^-1 f, f the forcing's distribution over the physical DoFs per unit amplitude. */
static double forcing_input(const rths_plant *p, int i) {
    int n = p->n;
    if (!p->forcing_shape) return p->minv[i + p->forcing_index * n];
    double s = 0;
    for (int l = 0; l < n; l++)
        s += p->minv[i + l * n] * p->forcing_shape[l];
    return s;
}

/* Exact response of one side over a sample to the held target and the static force: the
 * exponential of [[A h, U h, 0], [0, 0, I h], [0, 0, 0]] with U = (target, static) input
 * columns, for inputs a(tau) = a0 + d tau (Van Loan's block form of the hold integrals). */
static int build_side(rths_plant *p, int compressed, double *kk) {
    /* augmented: [state | target, static | their ramps | the forcing's chain of 4 integrators |
     * the further actuators' target and slope pairs] */
    int n = p->n, nz = p->nz, more = 2 * (p->ni - 1), N = nz + 8 + more;
    double *aug = rths_mat_new(N, N), *e = rths_mat_new(N, N);
    exact_side *sd = &p->side[compressed];
    sd->g_more = more > 0 ? calloc((size_t)(nz * more), sizeof(double)) : NULL;
    sd->phi = calloc((size_t)nz * (size_t)p->nz_padded, sizeof(double));
    sd->g_target_start = calloc((size_t)nz, sizeof(double));
    sd->g_target_slope = calloc((size_t)nz, sizeof(double));
    sd->g_static = calloc((size_t)nz, sizeof(double));
    int rc = aug && e && sd->phi && sd->g_target_start && sd->g_target_slope && sd->g_static &&
                     (more == 0 || sd->g_more)
                 ? 0
                 : -1;
    for (int k = 0; k < 4; k++)
        if (!(sd->g_forcing[k] = calloc((size_t)nz, sizeof(double)))) rc = -1;
    if (!rc) {
        side_state_matrix(p, compressed, kk, aug, N);
        for (int i = 0; i < n; i++) {
            double target_col = p->lag_rate > 0 ? 0.0 : actuator_input(p, i, 0);
            if (p->tf) target_col = p->minv[i + (n - 1) * n] * p->act_out * p->act_d;
            double static_col = 0;
            for (int l = 0; l < n; l++)
                static_col += p->minv[i + l * n] * p->static_force[l];
            aug[n + i + (size_t)nz * N] = target_col;
            aug[n + i + (size_t)(nz + 1) * N] = static_col;
        }
        if (p->lag_rate > 0) aug[2 * n + (size_t)nz * N] = p->lag_rate;
        for (int i = 0; p->tf && i < p->na; i++)
            aug[2 * n + i + (size_t)nz * N] = p->act_bu[i];
        aug[nz + (size_t)(nz + 2) * N] = 1.0;
        aug[nz + 1 + (size_t)(nz + 3) * N] = 1.0;
        /* w0' = w1, w1' = w2, w2' = w3: w0(tau) = sum_k w_k(0) tau^k / k! drives the forcing */
        for (int i = 0; p->forcing_index >= 0 && i < n; i++)
            aug[n + i + (size_t)(nz + 4) * N] = forcing_input(p, i);
        for (int k = 0; k < 3; k++)
            aug[nz + 4 + k + (size_t)(nz + 5 + k) * N] = 1.0;
        /* actuators 1..ni-1: a target column and its slope each, after the forcing's chain */
        for (int d = 1; d < p->ni; d++) {
            int col = nz + 8 + 2 * (d - 1);
            for (int i = 0; i < n && p->lag_rate <= 0; i++)
                aug[n + i + (size_t)col * N] = actuator_input(p, i, d);
            if (p->lag_rate > 0) aug[2 * n + d + (size_t)col * N] = p->lag_rate;
            aug[col + (size_t)(col + 1) * N] = 1.0;
        }
        for (size_t i = 0; i < (size_t)N * N; i++)
            aug[i] *= p->h;
        rc = rths_expm(N, aug, e);
    }
    if (!rc) {
        for (int j = 0; j < nz; j++)
            for (int i = 0; i < nz; i++)
                sd->phi[j + i * p->nz_padded] = e[i + (size_t)j * N]; /* read by rows */
        for (int i = 0; i < nz; i++) {
            sd->g_target_start[i] = e[i + (size_t)nz * N];
            sd->g_static[i] = e[i + (size_t)(nz + 1) * N];
            /* d = (T1 - T0) / h */
            sd->g_target_slope[i] = e[i + (size_t)(nz + 2) * N] / p->h;
            for (int k = 0; k < 4; k++)
                sd->g_forcing[k][i] = e[i + (size_t)(nz + 4 + k) * N];
            for (int d = 1; d < p->ni; d++) {
                int col = nz + 8 + 2 * (d - 1);
                sd->g_more[i + (size_t)(2 * (d - 1)) * nz] = e[i + (size_t)col * N];
                sd->g_more[i + (size_t)(2 * (d - 1) + 1) * nz] =
                    e[i + (size_t)(col + 1) * N] / p->h;
            }
        }
    }
    rths_mat_free(aug);
    rths_mat_free(e);
    return rc;
}

/* The actuator's states. The shaker: its lag's force (or none). A transfer function
 * F = (N U - k_v V) / D: observer canonical form with D made monic, x' = A x + b_u u + b_v v,
 * F = x[na - 1] + d u (A: ones below the diagonal, -D's coefficients in the last column). */
static int actuator_realise(rths_plant *p, const rths_actuator_options *a, rths_error *err) {
    if (a->model != RTHS_ACTUATOR_TRANSFER_FUNCTION) {
        p->na = p->lag_rate > 0 ? p->ni : 0; /* one lag per actuator */
        p->command_limit = a->force_clip ? a->force_limit_n : 0;
        return RTHS_OK;
    }
    int nd = a->denominator_count, nn = a->numerator_count, order = nd - 1;
    /* the velocity path V(s): the polynomial, or the constant as one of degree 0 */
    int nv = a->velocity_feedback_count > 0 ? a->velocity_feedback_count : 1;
    const double *vpoly =
        a->velocity_feedback_count > 0 ? a->velocity_feedback_poly : &a->velocity_feedback;
    int finite = nv <= RTHS_ACTUATOR_MAX_ORDER;
    for (int i = 0; finite && i < nv; i++)
        finite &= isfinite(vpoly[i]);
    for (int i = 0; i < nd && i <= RTHS_ACTUATOR_MAX_ORDER; i++)
        finite &= isfinite(a->denominator[i]);
    for (int i = 0; i < nn && i <= RTHS_ACTUATOR_MAX_ORDER; i++)
        finite &= isfinite(a->numerator[i]);
    if (nd < 1 || nd > RTHS_ACTUATOR_MAX_ORDER + 1 || nn < 1 || nn > nd || !finite ||
        a->denominator[0] == 0)
        return rths_error_set(err, RTHS_EINPUT,
                              "transfer_function actuator: %d numerator and %d denominator "
                              "coefficients; needs 1 <= numerator <= denominator <= %d, finite, "
                              "a nonzero leading denominator coefficient",
                              nn, nd, RTHS_ACTUATOR_MAX_ORDER + 1);
    int velocity_nonzero = 0;
    for (int i = 0; i < nv; i++)
        velocity_nonzero |= vpoly[i] != 0;
    if (order == 0 && velocity_nonzero)
        return rths_error_set(err, RTHS_EINPUT,
                              "transfer_function actuator: velocity feedback needs a denominator "
                              "of order 1 or more");
    /* strictly proper: a velocity term through D's degree would feed the velocity straight into
     * the force, outside the observer form's states */
    if (velocity_nonzero && nv > order)
        return rths_error_set(err, RTHS_EINPUT,
                              "transfer_function actuator: the velocity feedback V(s) has degree "
                              "%d; over a denominator of degree %d it must be at most %d",
                              nv - 1, order, order - 1);
    p->tf = 1;
    p->na = order;
    p->lag_rate = 0;
    p->act_spring = a->displacement_output ? a->connection_stiffness_n_per_m : 0.0;
    p->act_out = a->displacement_output ? a->connection_stiffness_n_per_m : 1.0;
    if (a->displacement_output && !(a->connection_stiffness_n_per_m > 0))
        return rths_error_set(err, RTHS_EINPUT,
                              "transfer_function actuator with displacement output: the "
                              "connection stiffness must be > 0");
    if (a->displacement_output && a->force_clip)
        return rths_error_set(err, RTHS_EINPUT,
                              "a force clip needs a force-output actuator (a displacement-output "
                              "one can trip on its force: force_action fault)");
    double lead = a->denominator[0], dk[RTHS_ACTUATOR_MAX_ORDER + 1],
           nk[RTHS_ACTUATOR_MAX_ORDER + 1] = {0};
    for (int k = 0; k <= order; k++)
        dk[k] = a->denominator[order - k] / lead; /* ascending powers, monic */
    for (int k = 0; k < nn; k++)
        nk[k] = a->numerator[nn - 1 - k] / lead;
    p->act_d = nk[order];
    size_t na = (size_t)(order > 0 ? order : 1);
    p->act_a = calloc(na * na, sizeof(double));
    p->act_bu = calloc(na, sizeof(double));
    p->act_bv = calloc(na, sizeof(double));
    if (!p->act_a || !p->act_bu || !p->act_bv)
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < order; i++) {
        if (i > 0) p->act_a[i + (i - 1) * order] = 1.0;
        p->act_a[i + (order - 1) * order] = -dk[i];
        p->act_bu[i] = nk[i] - dk[i] * p->act_d;
    }
    /* V's coefficients, ascending, enter like N's: b_v[i] = -v_i / lead (V strictly proper) */
    for (int i = 0; velocity_nonzero && i < nv; i++)
        p->act_bv[i] = -vpoly[nv - 1 - i] / lead;
    if (a->force_clip) {
        /* the force command is the static gain N(0) / D(0) times the demand */
        double g0 = dk[0] != 0 ? nk[0] / dk[0] : INFINITY;
        if (!(isfinite(g0) && g0 != 0))
            return rths_error_set(err, RTHS_EINPUT,
                                  "transfer_function actuator: a force clip needs a finite, "
                                  "nonzero static gain N(0)/D(0)");
        p->command_limit = a->force_limit_n / fabs(g0);
    }
    return RTHS_OK;
}

static int plant_alloc(rths_plant *p, int n, int delay) {
    size_t nn = (size_t)n * (size_t)n;
    p->nz = 2 * n + p->na;
    p->minv = calloc(nn, sizeof(double));
    p->c = calloc(nn, sizeof(double));
    p->k = calloc(nn, sizeof(double));
    p->static_force = calloc((size_t)n, sizeof(double));
    p->nz_padded = (p->nz + 3) / 4 * 4;
    p->z = calloc((size_t)p->nz_padded, sizeof(double));
    p->z_next = calloc((size_t)p->nz, sizeof(double));
    p->rk = calloc(11 * (size_t)n, sizeof(double)); /* RK4 stages and the force scratch */
    /* one delay line per actuator, delay + 1 long each, sharing the write position */
    p->delay_line = calloc(((size_t)delay + 1) * (size_t)p->ni, sizeof(double));
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
 * interface), the interface block with the mass the rig carries (rig.interface_mass: the
 * assembly's full M_II, or the physical share (1 - p) M_II) plus the armature. */
static int plant_matrices(rths_plant *p, const rths_setup *setup) {
    const rths_split *s = &setup->split;
    int n = p->n, ni = p->ni;
    double *m = rths_mat_new(n, n);
    if (!m) return -1;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            m[i + j * n] = RTHS_AT(s->mass_phys, n, i, j);
            p->c[i + j * n] = RTHS_AT(s->damping_phys, n, i, j);
            p->k[i + j * n] = RTHS_AT(s->stiffness_phys, n, i, j);
        }
    /* the interface block carries the rig's interface mass (setup.h), each actuator its
     * armature: on its DoF, or at its point through the transform, T diag(armature) T^T */
    for (int d = 0; d < ni; d++)
        for (int e = 0; e < ni; e++) {
            double arm = d == e ? p->opt.armature_mass_kg : 0.0;
            if (p->act_t) {
                arm = 0;
                for (int a = 0; a < ni; a++)
                    arm += p->act_t[d + a * ni] * p->act_t[e + a * ni] * p->opt.armature_mass_kg;
            }
            m[(n - ni + d) + (n - ni + e) * n] = rths_setup_rig_interface_mass(setup, d, e) + arm;
        }
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
    for (int d = 0; d < s->n_int; d++)
        to_phys[s->int_dofs[d]] = s->np - s->n_int + d;
    return to_phys;
}

static int plant_leg_and_loads(rths_plant *p, const rths_setup *setup, const int *to_phys,
                               rths_error *err) {
    const rths_split *s = &setup->split;
    for (int i = 0; i < setup->assembly.n; i++)
        if (to_phys[i] >= 0 && setup->static_force)
            p->static_force[to_phys[i]] = setup->static_force[i];
    p->forcing_index = -1;
    if (setup->base_excitation && setup->forcing_shape) {
        /* the interface's share acts through the numerical side (controller.h) */
        p->forcing_shape = calloc((size_t)p->n, sizeof(double));
        if (!p->forcing_shape) return rths_error_set(err, RTHS_EFAIL, "out of memory");
        for (int i = 0; i < s->n_phys; i++) {
            p->forcing_shape[i] = setup->forcing_shape[s->phys_dofs[i]];
            if (p->forcing_shape[i] != 0) p->forcing_index = i; /* any: "the plant forces" */
        }
    } else {
        for (int i = 0; i < s->n_phys; i++)
            if (s->phys_dofs[i] == setup->forcing_dof) p->forcing_index = i;
    }
    p->leg_upper = -1;
    /* the physical side's nonlinearity: one bilinear leg (its kink located inside the sample);
     * the numerical side's elements are the controller's */
    const rths_nl_element *leg = NULL;
    for (int e = 0; e < setup->n_nonlinear; e++) {
        const rths_nl_element *el = &setup->nonlinear[e];
        if (el->numerical) continue;
        if (el->type != RTHS_NL_BILINEAR || leg)
            return rths_error_set(err, RTHS_EINPUT,
                                  "the virtual plant models one bilinear leg on the physical "
                                  "side; nonlinear element %d (%s, DoFs %d-%d) on the physical "
                                  "side is not modelled by it (place it on the numerical side)",
                                  e + 1, rths_nl_type_name(el->type), el->dof_i + 1, el->dof_j + 1);
        leg = el;
    }
    if (!leg) return RTHS_OK;
    p->leg_upper = to_phys[leg->dof_i];
    p->leg_lower = leg->dof_j < 0 ? -1 : to_phys[leg->dof_j];
    if (p->leg_upper < 0 || (leg->dof_j >= 0 && p->leg_lower < 0))
        return rths_error_set(err, RTHS_EINPUT, "the bilinear leg must join physical DoFs");
    p->leg_k = leg->leg_stiffness_n_per_m;
    p->leg_ratio = leg->ratio;
    p->leg_extra_k = leg->k;
    return RTHS_OK;
}

/* 1 when the physical side carries a nonlinear element (the plant's bilinear leg). */
static int physical_nonlinear(const rths_setup *setup) {
    return rths_setup_nonlinear_count(setup, 0) > 0;
}

/* The rows of accel_rows: a sensor reads only the interface DoFs' accelerations, so the plant
 * applies M^-1's interface rows to its matrices once here instead of forming every DoF's force
 * each sample (the extension stiffness K; the leg's extra compression force enters by its own
 * coefficient). -1: out of memory. */
static int accel_rows_init(rths_plant *p) {
    int n = p->n, ni = p->ni, len = 2 * n + ni + 3;
    p->accel_row_len = len;
    p->accel_rows = calloc((size_t)(ni * len), sizeof(double));
    if (!p->accel_rows) return -1;
    for (int d = 0; d < ni; d++) {
        int row = n - ni + d;
        double *r = p->accel_rows + (size_t)(d * len);
        for (int j = 0; j < n; j++)
            for (int l = 0; l < n; l++) {
                r[j] -= p->minv[row + l * n] * p->k[l + j * n];
                r[n + j] -= p->minv[row + l * n] * p->c[l + j * n];
            }
        for (int a = 0; a < ni; a++)
            r[2 * n + a] = actuator_input(p, row, a);
        for (int l = 0; l < n; l++)
            r[2 * n + ni] += p->minv[row + l * n] * p->static_force[l];
        if (p->forcing_shape || p->forcing_index >= 0) r[2 * n + ni + 1] = forcing_input(p, row);
        if (p->leg_upper >= 0)
            r[2 * n + ni + 2] = -p->minv[row + p->leg_upper * n] +
                                (p->leg_lower >= 0 ? p->minv[row + p->leg_lower * n] : 0.0);
    }
    return 0;
}

static sensor_channel sensor_channel_of(int noise, const rths_sensor_spec *spec,
                                        const rths_adc_spec *adc) {
    int volts_noise = noise && adc->noise_v > 0;
    return (sensor_channel){.noisy = noise != 0,
                            .gain = 1 + spec->gain_error,
                            .offset = spec->offset,
                            .noise_std = spec->noise_std,
                            .quantum = spec->quantum,
                            .per_quantum = spec->quantum > 0 ? 1.0 / spec->quantum : 0.0,
                            .converter = adc->bits > 0 || volts_noise,
                            .adc_bits = adc->bits,
                            .adc_range_v = adc->range_v,
                            .units_per_v = adc->units_per_v,
                            .per_unit_v = adc->units_per_v != 0 ? 1.0 / adc->units_per_v : 0.0,
                            .adc_noise_v = volts_noise ? adc->noise_v : 0.0};
}

static void sensors_init(rths_plant *p) {
    const rths_plant_options *o = &p->opt;
    p->sensor[SENSOR_LASER] = sensor_channel_of(o->noise, &o->laser, &o->laser_adc);
    p->sensor[SENSOR_ACCELEROMETER] =
        sensor_channel_of(o->noise, &o->accelerometer, &o->accelerometer_adc);
    p->sensor[SENSOR_LOAD_CELL] = sensor_channel_of(o->noise, &o->load_cell, &o->load_cell_adc);
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
    if (s->n_int < 1 || s->n_int > RTHS_MAX_INTERFACE_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "the split has %d interface DoFs; the virtual plant drives 1 to %d "
                              "(one actuator each, RTHS_MAX_INTERFACE_DOFS in signals.h)",
                              s->n_int, RTHS_MAX_INTERFACE_DOFS);
    if (s->n_int > 1 && (opt->actuator.model == RTHS_ACTUATOR_TRANSFER_FUNCTION ||
                         opt->substeps_per_sample > 0 || physical_nonlinear(setup)))
        return rths_error_set(err, RTHS_EINPUT,
                              "with %d interface DoFs the virtual plant runs shakers on the exact "
                              "integrator of a linear structure (rig.actuator: transfer_function, "
                              "rig.plant_integrator: rk4 and the bilinear leg drive one actuator)",
                              s->n_int);
    if ((setup->actuator_transform || setup->sensor_transform) &&
        (opt->actuator.model == RTHS_ACTUATOR_TRANSFER_FUNCTION || opt->substeps_per_sample > 0 ||
         physical_nonlinear(setup)))
        return rths_error_set(err, RTHS_EINPUT,
                              "actuator and sensor transforms (rig.actuators, rig.lasers) run "
                              "shakers on the exact integrator of a linear structure (not with "
                              "rig.actuator: transfer_function, rig.plant_integrator: rk4 or the "
                              "bilinear leg)");
    if (!(sample_rate_hz > 0 && isfinite(sample_rate_hz)) || !(opt->gain_n_per_v > 0) ||
        !(opt->delay_s >= 0 && opt->delay_s * sample_rate_hz < 1e7) || opt->lag_cutoff_hz < 0 ||
        opt->armature_mass_kg < 0 || opt->substeps_per_sample < 0)
        return rths_error_set(err, RTHS_EINPUT, "invalid shaker options");
    int tf = opt->actuator.model == RTHS_ACTUATOR_TRANSFER_FUNCTION;
    if (tf && (opt->substeps_per_sample > 0 || physical_nonlinear(setup)))
        return rths_error_set(err, RTHS_EINPUT,
                              "the transfer_function actuator runs on the exact plant integrator "
                              "of a linear structure (rig.plant_integrator: rk4 and the bilinear "
                              "leg's kink crossings model the shaker only)");
    int delay = (int)lround(opt->delay_s * sample_rate_hz);
    rths_plant *p = calloc(1, sizeof *p);
    if (!p) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    p->opt = *opt;
    p->n = n;
    p->ni = s->n_int;
    p->h = 1.0 / sample_rate_hz;
    p->delay_samples = delay;
    p->lag_rate = opt->lag_cutoff_hz > 0 ? 2 * M_PI * opt->lag_cutoff_hz : 0;
    /* the armature is the shaker's; a transfer function's moving mass belongs to the structure */
    p->armature_kg = tf ? 0.0 : opt->armature_mass_kg;
    p->opt.armature_mass_kg = p->armature_kg;
    int *to_phys = NULL;
    int rc = actuator_realise(p, &opt->actuator, err);
    if (!rc && (plant_alloc(p, n, delay) || !(to_phys = physical_index(setup))))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");

    if (!rc && setup->actuator_transform &&
        !(p->act_t = rths_mat_dup(setup->actuator_transform, s->n_int, s->n_int)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc && setup->sensor_transform &&
        !(p->sens_t = rths_mat_dup(setup->sensor_transform, s->n_int, s->n_int)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");

    if (!rc && plant_matrices(p, setup))
        rc = rths_error_set(err, RTHS_EFAIL, "singular physical mass matrix");
    if (!rc) rc = plant_leg_and_loads(p, setup, to_phys, err);
    free(to_phys);
    double *kk = rc ? NULL : rths_mat_new(n, n);
    for (int side = 0; side < 2 && !rc; side++)
        if (!kk || build_side(p, side, kk))
            rc = rths_error_set(err, RTHS_EFAIL, "could not discretise the plant");
    rths_mat_free(kk);
    if (!rc && (static_start(p) || accel_rows_init(p)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (rc) {
        rths_plant_destroy(p);
        return rc;
    }
    rths_rng_seed(&p->rng, opt->seed);
    p->normal_next = NORMAL_POOL;
    sensors_init(p);
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

/* rig.noise: lab, the follow-up's laboratory (opt->noise = 2): sensors ten times noisier than the
 * default rig's, and a random force on the physical interface, held per sample (amplifier noise
 * and the disturbances no sensor sees), so that a new point's first residual is only a few times
 * the tolerance. The sensors' own keys still override these levels. */
enum { PLANT_NOISE_LAB = 2 };
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

/* A list of at most RTHS_ACTUATOR_MAX_ORDER + 1 coefficients into a fixed array. */
static int coefficients_read(rths_config *cfg, const char *key, int required, double *out,
                             int *count, rths_error *err) {
    double *v = NULL;
    int n = 0, rc = rths_config_get_double_list(cfg, key, required, &v, &n, err);
    if (!rc && n > RTHS_ACTUATOR_MAX_ORDER + 1)
        rc = rths_config_error_at(cfg, key, err, "%d coefficients; at most %d (order %d)", n,
                                  RTHS_ACTUATOR_MAX_ORDER + 1, RTHS_ACTUATOR_MAX_ORDER);
    if (!rc && rths_config_has(cfg, key) && n == 0)
        rc = rths_config_error_at(cfg, key, err, "needs at least one coefficient");
    for (int i = 0; !rc && i < n; i++)
        out[i] = v[i];
    if (!rc && n > 0) *count = n;
    free(v);
    return rc;
}

/* rig.sensors.NAME.adc_bits, adc_range_v, units_per_v, noise_v */
static int adc_config_read(rths_config *cfg, const char *name, rths_adc_spec *adc,
                           rths_error *err) {
    char k_bits[96], k_range[96], k_units[96], k_noise[96];
    snprintf(k_bits, sizeof k_bits, "rig.sensors.%s.adc_bits", name);
    snprintf(k_range, sizeof k_range, "rig.sensors.%s.adc_range_v", name);
    snprintf(k_units, sizeof k_units, "rig.sensors.%s.units_per_v", name);
    snprintf(k_noise, sizeof k_noise, "rig.sensors.%s.noise_v", name);
    long bits = adc->bits;
    int rc;
    if ((rc = rths_config_get_int(cfg, k_bits, 0, bits, 0, 32, &bits, err)) ||
        (rc = rths_config_get_double_ex(cfg, k_range, 0, adc->range_v, 0, 1e4, RTHS_CONFIG_LO_OPEN,
                                        &adc->range_v, err)) ||
        (rc = rths_config_get_double_ex(cfg, k_units, 0, adc->units_per_v, 0, 1e9,
                                        RTHS_CONFIG_LO_OPEN, &adc->units_per_v, err)) ||
        (rc = rths_config_get_double(cfg, k_noise, 0, adc->noise_v, 0, 1e3, &adc->noise_v, err)))
        return rc;
    adc->bits = (int)bits;
    return RTHS_OK;
}

/* rig.actuator.limits and rig.actuator.dac: for either model. */
static int actuator_limits_read(rths_config *cfg, rths_actuator_options *a, rths_error *err) {
    static const char *const clip[] = {"fault", "clip", NULL}, *const flag[] = {"fault", "flag",
                                                                                NULL};
    long bits = a->dac_bits;
    int rc;
    if ((rc = rths_config_get_double(cfg, "rig.actuator.limits.force_n", 0, a->force_limit_n, 0,
                                     1e9, &a->force_limit_n, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.limits.force_action", 0, a->force_clip,
                                     clip, &a->force_clip, err)) ||
        (rc = rths_config_get_double(cfg, "rig.actuator.limits.stroke_m", 0, a->stroke_limit_m, 0,
                                     100, &a->stroke_limit_m, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.limits.stroke_action", 0, a->stroke_flag,
                                     flag, &a->stroke_flag, err)) ||
        (rc = rths_config_get_double(cfg, "rig.actuator.limits.velocity_m_per_s", 0,
                                     a->velocity_limit_m_per_s, 0, 1e3, &a->velocity_limit_m_per_s,
                                     err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.limits.velocity_action", 0,
                                     a->velocity_flag, flag, &a->velocity_flag, err)) ||
        (rc = rths_config_get_int(cfg, "rig.actuator.dac.bits", 0, bits, 0, 32, &bits, err)) ||
        (rc = rths_config_get_double_ex(cfg, "rig.actuator.dac.range_v", 0, a->dac_range_v, 0, 1e4,
                                        RTHS_CONFIG_LO_OPEN, &a->dac_range_v, err)))
        return rc;
    a->dac_bits = (int)bits;
    return RTHS_OK;
}

/* rig.actuator.velocity_feedback: a number k_v (V(s) = k_v) or a list, V(s) in descending
 * powers of s (plant.h), each coefficient within +-1e15. */
static int velocity_feedback_read(rths_config *cfg, rths_actuator_options *a, rths_error *err) {
    static const char *const key = "rig.actuator.velocity_feedback";
    double *list = NULL;
    int count = 0;
    rths_error local;
    int rc = rths_config_get_double_list(cfg, key, 0, &list, &count, &local);
    if (rc != RTHS_OK || count == 0) {
        free(list);
        /* a list with a bad entry: its own message, not the scalar reader's "got a list" */
        if (rc != RTHS_OK && !strstr(local.msg, "expected a list")) {
            *err = local;
            return rc;
        }
        a->velocity_feedback_count = 0;
        return rths_config_get_double(cfg, key, 0, 0, -1e15, 1e15, &a->velocity_feedback, err);
    }
    if (count > RTHS_ACTUATOR_MAX_ORDER) rc = RTHS_EINPUT;
    for (int i = 0; !rc && i < count; i++)
        if (!(fabs(list[i]) <= 1e15)) {
            rc = rths_config_error_at(cfg, key, err,
                                      "entry %d: must be a finite number within +-1e15 (got %g)",
                                      i + 1, list[i]);
            free(list);
            return rc;
        }
    if (rc) {
        free(list);
        return rths_config_error_at(cfg, key, err,
                                    "%d coefficients; at most %d (degree below the denominator's, "
                                    "at most %d)",
                                    count, RTHS_ACTUATOR_MAX_ORDER, RTHS_ACTUATOR_MAX_ORDER);
    }
    for (int i = 0; i < count; i++)
        a->velocity_feedback_poly[i] = list[i];
    a->velocity_feedback_count = count;
    a->velocity_feedback = 0;
    free(list);
    return RTHS_OK;
}

/* rig.actuator: the model and, for transfer_function, its coefficients, delay and hold. */
static int actuator_config_read(rths_config *cfg, rths_plant_options *opt, rths_error *err) {
    static const char *const models[] = {"shaker", "transfer_function", NULL};
    static const char *const outputs[] = {"force", "displacement", NULL};
    static const char *const holds[] = {"linear", "step", NULL};
    rths_actuator_options *a = &opt->actuator;
    int model = (int)a->model, output = 0, rc;
    if ((rc = rths_config_get_choice(cfg, "rig.actuator.model", 0, model, models, &model, err)) ||
        (rc = actuator_limits_read(cfg, a, err)))
        return rc;
    a->model = (rths_actuator_model)model;
    int tf = a->model == RTHS_ACTUATOR_TRANSFER_FUNCTION;
    static const char *const tf_keys[] = {
        "numerator", "denominator", "velocity_feedback",           "output",
        "delay_s",   "hold",        "connection_stiffness_n_per_m"};
    for (int i = 0; !tf && i < 7; i++) {
        char key[64];
        snprintf(key, sizeof key, "rig.actuator.%s", tf_keys[i]);
        if (rths_config_has(cfg, key))
            return rths_config_error_at(cfg, key, err,
                                        "applies to rig.actuator.model: transfer_function only");
    }
    if (!tf) return RTHS_OK;
    /* a transfer function's demand goes through a DAC (held as a step) with no delay unless
     * told: the shaker's defaults do not carry over */
    int hold = 1;
    opt->delay_s = 0;
    if ((rc = coefficients_read(cfg, "rig.actuator.numerator", 1, a->numerator, &a->numerator_count,
                                err)) ||
        (rc = coefficients_read(cfg, "rig.actuator.denominator", 1, a->denominator,
                                &a->denominator_count, err)) ||
        (rc = velocity_feedback_read(cfg, a, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.output", 0, 0, outputs, &output, err)) ||
        (rc = rths_config_get_double(cfg, "rig.actuator.delay_s", 0, 0, 0, 0.1, &opt->delay_s,
                                     err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.hold", 0, hold, holds, &hold, err)))
        return rc;
    opt->linear_hold = hold == 0;
    a->displacement_output = output == 1;
    if (a->displacement_output &&
        (rc = rths_config_get_double_ex(cfg, "rig.actuator.connection_stiffness_n_per_m", 1, 0, 0,
                                        1e12, RTHS_CONFIG_LO_OPEN, &a->connection_stiffness_n_per_m,
                                        err)))
        return rc;
    if (!a->displacement_output &&
        rths_config_has(cfg, "rig.actuator.connection_stiffness_n_per_m"))
        return rths_config_error_at(cfg, "rig.actuator.connection_stiffness_n_per_m", err,
                                    "applies to rig.actuator.output: displacement only");
    if (a->displacement_output && a->force_clip)
        return rths_config_error_at(cfg, "rig.actuator.limits.force_action", err,
                                    "clip needs rig.actuator.output: force (a displacement-output "
                                    "actuator can trip on its force: fault)");
    if (a->numerator_count > a->denominator_count)
        return rths_config_error_at(cfg, "rig.actuator.numerator", err,
                                    "degree %d above the denominator's %d: the actuator must be "
                                    "proper",
                                    a->numerator_count - 1, a->denominator_count - 1);
    if (a->denominator[0] == 0)
        return rths_config_error_at(cfg, "rig.actuator.denominator", err,
                                    "the leading coefficient must be nonzero");
    if (a->velocity_feedback_count >= a->denominator_count)
        return rths_config_error_at(
            cfg, "rig.actuator.velocity_feedback", err,
            "degree %d; over the denominator's degree %d it must be at most "
            "%d (V(s) x' / D(s) strictly proper)",
            a->velocity_feedback_count - 1, a->denominator_count - 1, a->denominator_count - 2);
    return RTHS_OK;
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
    rths_adc_spec *adcs[3] = {&opt->laser_adc, &opt->accelerometer_adc, &opt->load_cell_adc};
    for (int s = 0; s < 3; s++) {
        if ((rc = adc_config_read(cfg, sensors[s].name, adcs[s], err))) return rc;
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
    return actuator_config_read(cfg, opt, err);
}
