/* The virtual laboratory built from its options (see plant.h): the physical matrices, the
 * actuators' continuous states (shaker lag, transfer function in observer canonical form), each
 * side's exact discretisation (built once: the per-sample path in plant.c does no matrix
 * exponential), the sensors, and the static start. */
#include "plant/plant_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* The transfer function's coefficients (checked by the caller) in observer canonical form: D made
 * monic, x' = A x + b_u U + b_v x'_interface, output = last state + d U. Shared with
 * src/tune/pd_loop.c (plant_internal.h). */
void plant_tf_form_of(const rths_actuator_options *a, plant_tf_form *f) {
    memset(f, 0, sizeof *f);
    int nd = a->denominator_count, nn = a->numerator_count, order = nd - 1;
    /* the velocity path V(s): the polynomial, or the constant as one of degree 0 */
    int nv = a->velocity_feedback_count > 0 ? a->velocity_feedback_count : 1;
    const double *vpoly =
        a->velocity_feedback_count > 0 ? a->velocity_feedback_poly : &a->velocity_feedback;
    int velocity_nonzero = 0;
    for (int i = 0; i < nv; i++)
        velocity_nonzero |= vpoly[i] != 0;
    double lead = a->denominator[0], dk[RTHS_ACTUATOR_MAX_ORDER + 1],
           nk[RTHS_ACTUATOR_MAX_ORDER + 1] = {0};
    for (int k = 0; k <= order; k++)
        dk[k] = a->denominator[order - k] / lead; /* ascending powers, monic */
    for (int k = 0; k < nn; k++)
        nk[k] = a->numerator[nn - 1 - k] / lead;
    f->order = order;
    f->d = nk[order];
    for (int i = 0; i < order; i++) {
        if (i > 0) f->a[i + (i - 1) * order] = 1.0;
        f->a[i + (order - 1) * order] = -dk[i];
        f->bu[i] = nk[i] - dk[i] * f->d;
    }
    /* V's coefficients, ascending, enter like N's: b_v[i] = -v_i / lead (V strictly proper) */
    for (int i = 0; velocity_nonzero && i < nv && i < RTHS_ACTUATOR_MAX_ORDER; i++)
        f->bv[i] = -vpoly[nv - 1 - i] / lead;
    f->static_gain = dk[0] != 0 ? nk[0] / dk[0] : INFINITY;
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
    plant_tf_form form;
    plant_tf_form_of(a, &form);
    p->act_d = form.d;
    size_t na = (size_t)(order > 0 ? order : 1);
    p->act_a = calloc(na * na, sizeof(double));
    p->act_bu = calloc(na, sizeof(double));
    p->act_bv = calloc(na, sizeof(double));
    if (!p->act_a || !p->act_bu || !p->act_bv)
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    memcpy(p->act_a, form.a, sizeof(double) * (size_t)order * (size_t)order);
    memcpy(p->act_bu, form.bu, sizeof(double) * (size_t)order);
    memcpy(p->act_bv, form.bv, sizeof(double) * (size_t)order);
    if (a->force_clip) {
        /* the force command is the static gain N(0) / D(0) times the demand */
        double g0 = form.static_gain;
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
