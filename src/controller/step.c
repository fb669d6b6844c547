/* The per-sample real-time step (see controller.h). Nothing in rths_controller_step allocates,
 * locks, prints or calls LAPACK; tests/test_controller.c checks it. */
#include "rths/controller.h"

#include "controller/spsc.h"
#include "rths/nonlinear.h"

#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RING_CAPACITY 256
#define MAX_STATE (2 * RTHS_REALTIME_MAX_DOFS)
/* inputs of the numerical model: the force on each interface DoF, then the external forcing */
#define MAX_INPUTS (RTHS_MAX_INTERFACE_DOFS + 1)
#define MAX_IFACE RTHS_MAX_INTERFACE_DOFS
#define MAX_OUT RTHS_MAX_OUTPUT_DOFS
#define MAX_NL RTHS_MAX_NONLINEAR
/* Newton steps per sample at most for the nonlinear elements' end-of-sample forces: a smooth
 * element converges quadratically from the explicit guess in 2-3, a kink in 1-2 once its side is
 * known (docs/method.md, "Nonlinear elements in the real-time step") */
#define NL_NEWTON_STEPS 6

/* A numerical-side nonlinear element as the step sees it (nonlinear.h): its coordinate is
 * z[off + i] - z[off + j] (off 0: the deformation, nn: its rate; j < 0: the ground). */
typedef struct {
    rths_nl_element el;
    int i, j, off;
    int kink; /* bilinear or gap: the crossing located inside the sample (FOH moments) */
} nl_state;

/* Where an output DoF's displacement comes from (output.dofs, rths_period.output_dof). */
enum {
    OUT_SENSOR,    /* a physical DoF below the interface: its laser, displacement_m[index] */
    OUT_INTERFACE, /* an interface DoF: its physical signal, interface DoF index */
    OUT_STATE,     /* a numerical DoF integrated as it is: state coordinate index */
    OUT_REDUCED    /* a numerical DoF of a reduced model: out_row . the reduced coordinates */
};

/* A signal's running Fourier sums: the mean's, then (a_k, b_k) interleaved for k = 1..K, as in
 * harmonic_table, so the per-sample update is one loop of 2K products over both arrays */
typedef struct {
    double mean;
    double ab[2 * RTHS_MAX_HARMONICS];
} sums;

/* cos and sin of k theta, k = 1..RTHS_MAX_HARMONICS, at one phase: computed once per sample for
 * the targets and every signal's Fourier sums */
typedef struct {
    double cs[2 * RTHS_MAX_HARMONICS]; /* cos k theta, sin k theta for k = 1..K, as in sums */
} harmonic_table;

/* by the angle-addition recurrence from cos theta and sin theta */
static void harmonic_table_init(harmonic_table *t, double cos_theta, double sin_theta) {
    double ck = cos_theta, sk = sin_theta;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        t->cs[2 * k - 2] = ck, t->cs[2 * k - 1] = sk;
        double next = ck * cos_theta - sk * sin_theta;
        sk = sk * cos_theta + ck * sin_theta;
        ck = next;
    }
}

struct rths_controller {
    rths_controller_options opt;
    double h, rate;     /* the sample period, s, and its reciprocal, Hz (differences per sample
                           multiply by it: no division per sample) */
    int nn, nx, np;     /* numerical DoFs, its state size, physical DoFs (sensors) */
    int ni, n_inputs;   /* interface DoFs (one actuator each), numerical model inputs ni + 1 */
    int forcing_index;  /* forcing DoF in the numerical substructure's order */
    int host_numerical; /* split.numerical_solver: frequency: no numerical model here */
    /* inertial compensation mass, ni x ni, kg: the numerical interface block p M_int when the rig
     * carries the full interface mass, zero when it carries only its physical share */
    double m_comp[MAX_IFACE * MAX_IFACE];
    double kp[MAX_IFACE], kd[MAX_IFACE];   /* PD gains per interface DoF */
    double gkp[MAX_IFACE], gkd[MAX_IFACE]; /* grounding gains per interface DoF */
    /* Actuator and sensor transforms (setup.h) or gain matrices: transformed is 1 when any
     * applies. ni x ni, leading dimension MAX_IFACE, inverses formed at create. */
    int transformed;
    double t_eff[MAX_IFACE * MAX_IFACE]; /* T: interface efforts of the actuators' forces */
    double t_acc[MAX_IFACE * MAX_IFACE]; /* T^-T: interface accelerations from the actuators' */
    double s_inv[MAX_IFACE * MAX_IFACE]; /* S^-1: interface displacements from the lasers' */
    double gp[MAX_IFACE * MAX_IFACE], gd[MAX_IFACE * MAX_IFACE]; /* (actuator, DoF) PD gains */
    double ad[MAX_STATE * MAX_STATE], b_prev[MAX_STATE * MAX_INPUTS],
        b_curr[MAX_STATE * MAX_INPUTS];
    double z[MAX_STATE], u_prev[MAX_INPUTS];
    /* Nonlinear elements of the numerical substructure (n_nl 0: none, and the step is the linear
     * one): their forces enter as further inputs of the same discretisation, bg_prev / bg_curr
     * (nx x n_nl); sg_prev / sg_curr = C bg (n_nl x n_nl, C the elements' coordinate rows);
     * static_step: the discretised static forces on numerical DoFs per step (nx) */
    int n_nl, nl_foh, has_static;
    nl_state nl[MAX_NL];
    double bg_prev[MAX_STATE * MAX_NL], bg_curr[MAX_STATE * MAX_NL];
    double sg_prev[MAX_NL * MAX_NL], sg_curr[MAX_NL * MAX_NL];
    double static_step[MAX_STATE];
    int nl_newton_max; /* the most Newton steps one sample took (bench: worst-case cost) */
    /* a sparse model's numerical side: integrated as its Krylov reduction (krylov 1), the
     * reduction's report, the sparse side's order; the numerical interface masses (kg, or
     * kg m^2), for the grounding check's message */
    int krylov, krylov_full_dofs;
    rths_krylov_report krylov_rep;
    double m_num_iface[MAX_IFACE];
    /* commands */
    double omega, pending_omega, amplitude_n, pending_amplitude;
    int pending_forcing;
    double pending_since_s; /* controller time of the oldest pending change */
    int harmonics;
    double target_a[MAX_IFACE][RTHS_MAX_HARMONICS], target_b[MAX_IFACE][RTHS_MAX_HARMONICS];
    /* Smooth transitions (controller.transition_periods > 0; docs/method.md, "Smooth
     * transitions"): each change is reached along s(u) = smootherstep, u the phase advanced since
     * it began over that of transition_periods periods (1: none under way). The forcing's
     * frequency and amplitude glide from glide_*_from from a period boundary, so every site of a
     * multi-site test glides alike; the target's coefficients move from from_* (what was applied
     * when it changed, over from_harmonics harmonics) at the rate target_s_rate = ds/dt, from
     * the glide's start when a forcing change is pending (target_waits), else at once; the static
     * term moves over one period. */
    double from_a[MAX_IFACE][RTHS_MAX_HARMONICS], from_b[MAX_IFACE][RTHS_MAX_HARMONICS];
    double target_u, target_s, target_s_rate;
    int from_harmonics, target_waits, gliding;
    double glide_u, glide_omega_from, glide_omega_to, glide_amplitude_from, glide_amplitude_to;
    double static_u, static_from[MAX_IFACE], static_to[MAX_IFACE];
    double transition_per_rad; /* 1 / (2 pi transition_periods), set at create; 0 without */
    /* controller time at which the open period began (its predecessor's interpolated end, as
     * published), and what set_forcing and set_target last answered: the time from which
     * periods run (or glide) under the new setting (rths_controller_forcing_valid_from_s,
     * rths_controller_target_valid_from_s); glide_first_period: the open period is a glide's
     * first (a target set in it joins that forcing change) */
    double open_period_start_s, forcing_valid_from_s, target_valid_from_s;
    int glide_first_period;
    int feedback, armed;
    rths_rig_fault fault;
    rths_fault_detail fault_detail;       /* what latched it: channel, value, limit */
    int sensed_dof[RTHS_MAX_SENSED_DOFS]; /* assembly DoF (1-based) of each laser, sensor order */
    int int_dof[MAX_IFACE];               /* assembly DoF (1-based) of each interface DoF */
    /* the open period's integrity counts (rths_period): late, clipped-demand and
       saturated-sensor samples, from rths_controller_count_sample */
    int late_samples, clipped_demand_samples, saturated_sensor_samples;
    double ramp;        /* 0..1: scales demand, forcing and target */
    double ramp_step;   /* the ramp's change per sample, h / ramp_time_s (1 without a ramp) */
    double forcing_now; /* forcing amplitude of the last step (ramp included), N */
    double static_offset[MAX_IFACE]; /* mean physical interface displacement, last period, m */
    double demand[MAX_IFACE];        /* the last step's demand per actuator, V */
    /* signal state, per interface DoF */
    double time_s, theta;
    /* cos and sin of theta (tables[at_theta].cs[0], cs[1]) are advanced by rotation through
     * omega h (cos/sin of rotor_omega h) so a sample costs no trigonometry; set exactly at every
     * period start, which bounds the rounding drift to one period's worth of rotations (~1e-13) */
    double rotor_omega, cos_step, sin_step;
    double x_prev[MAX_IFACE], v_est[MAX_IFACE], velocity_alpha;
    /* grounding control's consistent samples */
    double x_last[MAX_IFACE], x_last_prev[MAX_IFACE], xi_last_prev[MAX_IFACE];
    int grounding_have;
    int have_prev;
    /* running Fourier sums of the open period, and the previous sample for the trapezoid:
       y_prev[3 d + (0 physical, 1 numerical, 2 force)] */
    sums acc_phys[MAX_IFACE], acc_num[MAX_IFACE], acc_force[MAX_IFACE];
    double y_prev[3 * MAX_IFACE];
    /* output.dofs: the listed DoFs' sources, their sums and previous samples (n_out 0: none,
       and the step skips all of it) */
    int n_out;
    int out_kind[MAX_OUT], out_index[MAX_OUT];
    double out_row[MAX_OUT][RTHS_REALTIME_MAX_DOFS];
    sums acc_out[MAX_OUT];
    double y_out_prev[MAX_OUT];
    /* The trapezoid summed point by point: a sample point enters the sums once, when both its
     * intervals are known, with their two weights together. left_weight: the weight the point
     * at theta (y_prev) has from the interval that ends there (0 at a period's start);
     * tables[at_theta]: cos/sin of k theta for it (and the phase's rotation); the other table
     * takes the next sample's end, and the two swap roles (no copy per sample). */
    double left_weight;
    harmonic_table tables[2];
    int at_theta;
    int period_samples, at_boundary;
    /* published periods: single producer (step), single consumer (pop) */
    rths_period ring_storage[RING_CAPACITY];
    rths_spsc ring;
    atomic_long dropped;
};

static void latch_detail(rths_controller *c, rths_rig_fault f, rths_fault_cause cause, int channel,
                         double value, double limit);

void rths_controller_defaults(rths_controller_options *opt) {
    opt->sample_rate_hz = 10000.0;
    opt->scheme = RTHS_SCHEME_DEFAULT;
    opt->kp_v_per_m = 100.0;
    opt->kd_v_s_per_m = 10.0;
    for (int d = 0; d < RTHS_MAX_INTERFACE_DOFS; d++)
        opt->kp_dof_v_per_m[d] = opt->kd_dof_v_s_per_m[d] = opt->grounding_kp_dof[d] =
            opt->grounding_kd_dof[d] = 0.0;
    opt->grounding_kp_n_per_m = 50000.0;
    /* 5x the seed's 200 N s/m: the grounding force vanishes at a match, so it cannot change a
     * converged result, but it damps the numerical side's transients after every new target,
     * which cuts the settling time per evaluation about threefold (bench frf) */
    opt->grounding_kd_n_s_per_m = 1000.0;
    opt->velocity_cutoff_hz = 1000.0;
    opt->demand_limit_v = 10.0;
    opt->displacement_limit_m = 0.01;
    opt->force_limit_n = 500.0;
    opt->ramp_time_s = 0.1;
    opt->track_static = 1;
    opt->transition_periods = 3;
    opt->min_frequency_hz = 0.1;
    opt->max_pending_s = 1.0;
    opt->plant_applies_forcing = 0;
    opt->max_overrun_share = 0.0;
    opt->gain_matrix_rows = opt->gain_matrix_cols = 0;
    memset(opt->kp_matrix, 0, sizeof opt->kp_matrix);
    memset(opt->kd_matrix, 0, sizeof opt->kd_matrix);
    rths_reduction_defaults(&opt->reduction);
    rths_krylov_defaults(&opt->krylov);
    opt->output_dofs = 0;
    memset(opt->output_dof, 0, sizeof opt->output_dof);
}

double rths_target_peak_bound_m(int harmonics, const double *a, const double *b) {
    double bound = 0;
    for (int k = 0; k < harmonics; k++)
        bound += hypot(a[k], b[k]);
    return bound;
}

/* The numerical substructure the step integrates must not be unstable on its own: a split whose
 * interface block was divided by the coupling rule of a spring chain (model.h) can leave a beam's
 * numerical stiffness indefinite (the follow-up's cantilever cut at 0.17 m: an eigenvalue of
 * -2.9e4 N/m), and its integration diverges within samples. Refused at create, by name. k: the
 * n x n stiffness integrated (the split's, or a sparse model's reduced one). */
static int numerical_stiffness_definite(int n, const double *stiffness, rths_error *err) {
    double complex *k = malloc(sizeof *k * (size_t)n * (size_t)n);
    if (!k) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n * n; i++)
        k[i] = stiffness[i];
    double ratio = rths_cmat_hermitian_eigen_ratio(n, k);
    free(k);
    /* rounding leaves a singular (free-floating) part at |ratio| ~ 1e-16 */
    if (ratio < -1e-9 && rths_mat_max_abs(stiffness, n, n) > 0)
        return rths_error_set(err, RTHS_EINPUT,
                              "the numerical substructure's stiffness is indefinite (smallest to "
                              "largest eigenvalue %.3g): the split's interface block does not suit "
                              "this structure, and the real-time integration would diverge",
                              ratio);
    return RTHS_OK;
}

/* A sparse model's numerical substructure (setup->sparse: no dense matrix of its order exists)
 * as its band-exact Krylov reduction over the sweep (krylov_reduce.h; docs/architecture.md,
 * "Sparse algebra"): the same Craig-Bampton shape (interface first and physical, inputs projected
 * by T^T), refused by controller.reduction.max_error when worse than that in the band. */
static int krylov_numerical(rths_controller *c, const rths_setup *setup, rths_reduced *red,
                            rths_error *err) {
    const rths_split *s = &setup->split;
    const rths_krylov_options *ko = &c->opt.krylov;
    if (!(ko->end_hz > ko->start_hz))
        return rths_error_set(err, RTHS_EINPUT,
                              "this model takes the sparse path (%d DoFs): its numerical "
                              "substructure is integrated in real time as a reduction exact over "
                              "the tested band, and no band is given: set continuation.start_hz "
                              "and continuation.end_hz (or split.numerical_solver: frequency)",
                              setup->assembly.n);
    int *dofs = NULL;
    int rc = rths_sparse_model_krylov_reduce(setup->sparse, ko, red, &dofs, &c->krylov_rep, err);
    /* the reduction orders the side as the split does (interface, then numerical DoFs) */
    for (int i = 0; !rc && i < s->nn; i++)
        if (dofs[i] != (i < s->n_int ? s->int_dofs[i] : s->num_dofs[i - s->n_int]))
            rc = rths_error_set(err, RTHS_EFAIL,
                                "the sparse numerical substructure's DoF %d is assembly DoF %d, "
                                "not the split's",
                                i + 1, dofs[i] + 1);
    free(dofs);
    if (!rc) rc = numerical_stiffness_definite(red->nr, red->stiffness, err);
    for (int d = 0; !rc && d < s->n_int; d++)
        c->m_num_iface[d] = setup->sparse->mass_ratio *
                            rths_sparse_get(&setup->sparse->mass, s->int_dofs[d], s->int_dofs[d]);
    c->krylov = !rc;
    c->krylov_full_dofs = s->nn;
    return rc;
}

/* The numerical model the step integrates, x_{k+1} = ad x_k + b_prev u_k + b_curr u_{k+1} with
 * inputs (interface force, forcing): the split's numerical substructure as it is, or, when the
 * reduction applies, its Craig-Bampton reduction (reduce.h; the interface stays coordinate 0, the
 * inputs are projected by T^T). An auto cutoff is lowered to fit RTHS_REALTIME_MAX_DOFS. A sparse
 * model's is always reduced, by krylov_numerical. */
static int build_numerical(rths_controller *c, const rths_setup *setup, int forcing_physical,
                           int base, rths_error *err) {
    const rths_split *s = &setup->split;
    const rths_reduction_options *ro = &c->opt.reduction;
    rths_reduced red = {0};
    const int sparse = setup->sparse != NULL;
    int rc = RTHS_OK, reduce = sparse || rths_reduction_applies(ro, s->nn);
    for (int d = 0; !sparse && d < s->n_int; d++)
        c->m_num_iface[d] = RTHS_AT(s->mass_num, s->nn, d, d);
    /* the DoFs a nonlinear element touches stay physical coordinates of the reduced model (its
     * deformation is then a coordinate difference, as unreduced): boundary coordinates after the
     * interface's, keep[m] becoming coordinate n_int + m (reduce.h) */
    int keep[2 * MAX_NL], n_keep = 0;
    for (int e = 0; reduce && e < c->n_nl; e++) {
        int ends[2] = {c->nl[e].i, c->nl[e].j};
        for (int k = 0; k < 2; k++) {
            int dof = ends[k], seen = dof < s->n_int; /* ground (-1) and interface DoFs stay */
            for (int m = 0; m < n_keep && !seen; m++)
                seen = keep[m] == dof;
            if (!seen) keep[n_keep++] = dof;
        }
    }
    if (sparse)
        rc = krylov_numerical(c, setup, &red, err);
    else if (reduce)
        rc = rths_reduce_craig_bampton_keeping(
            s->nn, s->n_int, s->mass_num, s->damping_num, s->stiffness_num, n_keep, keep,
            rths_reduction_cutoff_hz(ro, c->opt.sample_rate_hz),
            RTHS_REALTIME_MAX_DOFS - s->n_int - n_keep, ro->cutoff_hz <= 0, &red, err);
    int n = reduce ? red.nr : s->nn;
    if (!rc && n > RTHS_REALTIME_MAX_DOFS)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "the numerical substructure has %d DoFs; the real-time step integrates "
                            "at most %d (RTHS_REALTIME_MAX_DOFS): set controller.reduction.method "
                            "to craig_bampton (or auto), or split.numerical_solver to frequency",
                            n, RTHS_REALTIME_MAX_DOFS);
    const int ni = c->ni, n_in_lin = c->n_inputs;
    /* further inputs: one per nonlinear element (its force's direction e_i - e_j), then the
     * static forces on numerical DoFs (a constant input of 1) */
    const int n_in = n_in_lin + c->n_nl + c->has_static;
    double *input = rc ? NULL : rths_mat_new(s->nn, n_in), *a = NULL, *b = NULL;
    if (!rc && !input) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        for (int d = 0; d < ni; d++)
            input[d + (size_t)d * s->nn] = 1.0; /* column d: force on interface DoF d */
        /* column ni: external forcing on the model; none when the plant applies it; a base
         * excitation's -M 1 per m/s^2 on the interface and the numerical DoFs */
        double *forcing = input + (size_t)ni * s->nn;
        if (base) {
            for (int d = 0; d < ni; d++)
                forcing[d] = setup->forcing_shape[s->int_dofs[d]];
            for (int i = 0; i < s->n_num; i++)
                forcing[s->n_int + i] = setup->forcing_shape[s->num_dofs[i]];
        } else if (!forcing_physical) {
            forcing[c->forcing_index] = 1.0;
        }
        for (int e = 0; e < c->n_nl; e++) {
            double *col = input + (size_t)(n_in_lin + e) * s->nn;
            col[c->nl[e].i] = -1.0; /* the element pulls DoF i with -g, pushes j with +g */
            if (c->nl[e].j >= 0) col[c->nl[e].j] = 1.0;
        }
        if (c->has_static) {
            double *col = input + (size_t)(n_in_lin + c->n_nl) * s->nn;
            for (int i = 0; i < s->n_num; i++)
                col[s->n_int + i] = setup->static_force[s->num_dofs[i]];
        }
    }
    /* the elements' coordinates in the reduced model (the input columns above are in the
     * substructure's own DoFs and are projected by T^T below) */
    for (int e = 0; !rc && reduce && e < c->n_nl; e++) {
        nl_state *ne = &c->nl[e];
        int i = ne->i, j = ne->j; /* compared before any is renamed */
        for (int m = 0; m < n_keep; m++) {
            if (i == keep[m]) ne->i = s->n_int + m;
            if (j == keep[m]) ne->j = s->n_int + m;
        }
        ne->off = rths_nl_on_rate(&ne->el) ? n : 0; /* velocities follow the n coordinates */
    }
    double *reduced_input = !rc && reduce ? rths_mat_new(n, n_in) : NULL;
    if (reduced_input)
        rths_mat_mul(n, n_in, s->nn, 1.0, red.transform, 1, input, 0, 0.0, reduced_input);
    else if (!rc && reduce)
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    rths_discrete d = {0};
    if (!rc)
        rc = rths_state_space(n, reduce ? red.mass : s->mass_num,
                              reduce ? red.damping : s->damping_num,
                              reduce ? red.stiffness : s->stiffness_num, n_in,
                              reduce ? reduced_input : input, &a, &b, err);
    c->nn = n;
    c->nx = 2 * n;
    /* output DoFs of the numerical side: a state coordinate, or a row of q = T r */
    for (int j = 0; !rc && j < c->n_out; j++) {
        if (c->out_kind[j] != OUT_STATE || !reduce) continue;
        c->out_kind[j] = OUT_REDUCED;
        for (int k = 0; k < n; k++)
            c->out_row[j][k] = red.transform[c->out_index[j] + (size_t)k * (size_t)s->nn];
    }
    if (!rc) rc = rths_discretise(c->nx, n_in, a, b, c->h, c->opt.scheme, &d, err);
    if (!rc) {
        const size_t nx = (size_t)c->nx;
        memcpy(c->ad, d.ad, sizeof(double) * nx * nx);
        memcpy(c->b_prev, d.b_prev, sizeof(double) * nx * (size_t)n_in_lin);
        memcpy(c->b_curr, d.b_curr, sizeof(double) * nx * (size_t)n_in_lin);
        memcpy(c->bg_prev, d.b_prev + nx * n_in_lin, sizeof(double) * nx * (size_t)c->n_nl);
        memcpy(c->bg_curr, d.b_curr + nx * n_in_lin, sizeof(double) * nx * (size_t)c->n_nl);
        for (size_t i = 0; c->has_static && i < nx; i++)
            c->static_step[i] = d.b_prev[i + nx * (size_t)(n_in_lin + c->n_nl)] +
                                d.b_curr[i + nx * (size_t)(n_in_lin + c->n_nl)];
        /* sg = C bg: each element's coordinate's response to each element's force */
        for (int e = 0; e < c->n_nl; e++)
            for (int f = 0; f < c->n_nl; f++) {
                const nl_state *ne = &c->nl[e];
                const double *bp = c->bg_prev + nx * (size_t)f, *bc = c->bg_curr + nx * (size_t)f;
                c->sg_prev[e + f * MAX_NL] =
                    bp[ne->off + ne->i] - (ne->j >= 0 ? bp[ne->off + ne->j] : 0.0);
                c->sg_curr[e + f * MAX_NL] =
                    bc[ne->off + ne->i] - (ne->j >= 0 ? bc[ne->off + ne->j] : 0.0);
            }
        c->nl_foh = d.scheme == RTHS_SCHEME_EXACT_FOH;
    }
    free(a), free(b), free(input), free(reduced_input);
    rths_discrete_free(&d);
    rths_reduced_free(&red);
    return rc;
}

/* The numerical side's nonlinear elements in the numerical substructure's DoF order (interface
 * DoFs, then numerical ones), and whether static forces act on its numerical DoFs. */
static int numerical_elements(rths_controller *c, const rths_setup *setup, rths_error *err) {
    const rths_split *s = &setup->split;
    int n = setup->assembly.n;
    int *to_num = malloc(sizeof(int) * (size_t)n);
    if (!to_num) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n; i++)
        to_num[i] = -1;
    for (int d = 0; d < s->n_int; d++)
        to_num[s->int_dofs[d]] = d;
    for (int i = 0; i < s->n_num; i++)
        to_num[s->num_dofs[i]] = s->n_int + i;
    int rc = RTHS_OK;
    c->n_nl = 0;
    for (int e = 0; e < setup->n_nonlinear && !rc; e++) {
        const rths_nl_element *el = &setup->nonlinear[e];
        if (!el->numerical) continue;
        nl_state *ns = &c->nl[c->n_nl];
        ns->el = *el;
        ns->i = to_num[el->dof_i];
        ns->j = el->dof_j >= 0 ? to_num[el->dof_j] : -1;
        ns->off = rths_nl_on_rate(el) ? s->nn : 0;
        ns->kink = el->type == RTHS_NL_BILINEAR || el->type == RTHS_NL_GAP;
        if (ns->i < 0 || (el->dof_j >= 0 && ns->j < 0))
            rc = rths_error_set(err, RTHS_EINPUT,
                                "nonlinear element %d (DoFs %d-%d) is on the numerical side but "
                                "joins a physical DoF",
                                e + 1, el->dof_i + 1, el->dof_j + 1);
        c->n_nl++;
    }
    c->has_static = 0;
    for (int i = 0; i < s->n_num && setup->static_force; i++)
        c->has_static |= setup->static_force[s->num_dofs[i]] != 0;
    free(to_num);
    return rc;
}

/* The transforms' inverses and the gain matrices, formed here so that the step only multiplies:
 * interface displacements S^-1 y from the lasers y, accelerations T^-T a from the actuators'
 * accelerometers, efforts T f from their load cells; the demands G_p e + G_d e' of the errors e
 * per interface DoF, with G = T^-1 diag(gains per DoF) unless a gain matrix is given (the
 * actuators then produce the efforts g diag(gains) e, g the actuator's N/V). */
static int build_transforms(rths_controller *c, const rths_setup *setup, rths_error *err) {
    const rths_controller_options *opt = &c->opt;
    int ni = c->ni;
    c->transformed =
        setup->actuator_transform || setup->sensor_transform || opt->gain_matrix_rows > 0;
    if (!c->transformed) return RTHS_OK;
    if (opt->gain_matrix_rows > 0 && (opt->gain_matrix_rows != ni || opt->gain_matrix_cols != ni))
        return rths_error_set(err, RTHS_EINPUT,
                              "controller.kp_matrix and kd_matrix are %d x %d; with %d interface "
                              "DoFs and %d actuators they must be %d x %d",
                              opt->gain_matrix_rows, opt->gain_matrix_cols, ni, ni, ni, ni);
    double t[MAX_IFACE * MAX_IFACE], inv[MAX_IFACE * MAX_IFACE];
    double sm[MAX_IFACE * MAX_IFACE], sinv[MAX_IFACE * MAX_IFACE];
    for (int i = 0; i < ni; i++)
        for (int j = 0; j < ni; j++) {
            RTHS_AT(t, ni, i, j) = setup->actuator_transform
                                       ? RTHS_AT(setup->actuator_transform, ni, i, j)
                                       : (double)(i == j);
            RTHS_AT(sm, ni, i, j) = setup->sensor_transform
                                        ? RTHS_AT(setup->sensor_transform, ni, i, j)
                                        : (double)(i == j);
        }
    if (rths_mat_inverse(ni, t, inv) || rths_mat_inverse(ni, sm, sinv))
        return rths_error_set(err, RTHS_EINPUT, "singular actuator or sensor transform");
    for (int i = 0; i < ni; i++)
        for (int j = 0; j < ni; j++) {
            c->t_eff[i + j * MAX_IFACE] = RTHS_AT(t, ni, i, j);
            c->t_acc[i + j * MAX_IFACE] = RTHS_AT(inv, ni, j, i);
            c->s_inv[i + j * MAX_IFACE] = RTHS_AT(sinv, ni, i, j);
            int given = opt->gain_matrix_rows > 0;
            c->gp[i + j * MAX_IFACE] =
                given ? opt->kp_matrix[i + j * MAX_IFACE] : RTHS_AT(inv, ni, i, j) * c->kp[j];
            c->gd[i + j * MAX_IFACE] =
                given ? opt->kd_matrix[i + j * MAX_IFACE] : RTHS_AT(inv, ni, i, j) * c->kd[j];
        }
    return RTHS_OK;
}

/* The grounding control acts one sample late (it compares the last measured x with xi before the
 * step), so on a light interface DoF it destabilises the numerical model on its own: the seed's
 * 50000 N/m and 1000 N s/m on a beam's cut (milligrams on w, 1e-7 kg m^2 on theta) gave a
 * spectral radius far above 1 and non-finite values within 70 samples. The loop with the
 * physical side held still (x = 0), over w_k = (z_k, z_k-1, u_k-1):
 *   z_k+1 = (Ad + Bc G1) z_k + Bc G0 z_k-1 + Bp u_k-1,  u_k = G1 z_k + G0 z_k-1,
 * G1 = -(kp^ + kd^/h) and G0 = kd^/h on each interface DoF. Refused at create when unstable. */
static int grounding_stable(const rths_controller *c, const rths_split *s, rths_error *err) {
    const int ni = c->ni;
    double radius = rths_grounding_loop_radius(c->nx, c->n_inputs, c->ad, c->b_prev, c->b_curr,
                                               c->h, ni, c->gkp, c->gkd);
    if (radius < 0)
        return rths_error_set(err, RTHS_EFAIL,
                              "the eigenvalues of the grounding loop could not be computed");
    if (radius <= 1 + 1e-9) return RTHS_OK;
    int worst = 0;
    for (int d = 1; d < ni; d++)
        if (c->gkd[d] / c->m_num_iface[d] > c->gkd[worst] / c->m_num_iface[worst]) worst = d;
    double m = c->m_num_iface[worst];
    return rths_error_set(err, RTHS_EINPUT,
                          "the grounding control destabilises the numerical substructure "
                          "(spectral radius %.6g per sample): it acts one sample late, and "
                          "interface DoF %d (DoF %d) carries a numerical mass of only %.3g (kg, or "
                          "kg m^2 for a rotation) against grounding gains %g and %g; set "
                          "controller.grounding_kp_per_dof and grounding_kd_per_dof, e.g. kp below "
                          "%.3g and kd below %.3g for that DoF (m/h^2 / 10, m/h / 4)",
                          radius, worst + 1, s->int_dofs[worst] + 1, m, c->gkp[worst],
                          c->gkd[worst], 0.1 * m / (c->h * c->h), 0.25 * m / c->h);
}

int rths_controller_nonlinear_newton_steps(const rths_controller *c) {
    return c->nl_newton_max;
}

int rths_controller_numerical_dofs(const rths_controller *c) {
    return c->host_numerical ? 0 : c->nn;
}

int rths_controller_krylov_report(const rths_controller *c, rths_krylov_report *rep) {
    if (!c->krylov) return 0;
    *rep = c->krylov_rep;
    return 1;
}

void rths_controller_krylov_text(const rths_controller *c, char *buf, size_t size) {
    if (size == 0) return;
    buf[0] = 0;
    if (!c->krylov) return;
    const rths_krylov_report *r = &c->krylov_rep;
    snprintf(buf, size,
             "numerical substructure: sparse, %d DoFs, reduced in real time to %d DoFs (Krylov, "
             "%d shift(s)), interface FRF error %.3g at %g Hz (controller.reduction.max_error "
             "%g) over %d check points of %g-%g Hz; %.3g s in the check's solves, %.3g s "
             "building the basis",
             c->krylov_full_dofs, c->nn, r->shifts, r->max_error, r->at_hz, c->opt.krylov.max_error,
             r->check_points, c->opt.krylov.start_hz, c->opt.krylov.end_hz, r->truth_s, r->basis_s);
}

int rths_controller_check_sensed_dofs(const rths_split *s, rths_error *err) {
    if (s->np > RTHS_MAX_SENSED_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "the physical substructure has %d DoFs; the real-time controller "
                              "(fixed per-sample buffers, RTHS_MAX_SENSED_DOFS in signals.h) "
                              "senses at most %d",
                              s->np, RTHS_MAX_SENSED_DOFS);
    return RTHS_OK;
}

/* Where each of output.dofs is read: the step's own state for a numerical DoF, the sensors for a
 * physical one. */
static int output_sources(rths_controller *c, const rths_setup *setup, rths_error *err) {
    const rths_split *s = &setup->split;
    c->n_out = c->opt.output_dofs;
    for (int j = 0; j < c->n_out; j++) {
        const int dof = c->opt.output_dof[j];
        int found = 0;
        if (dof < 0 || dof >= s->n)
            return rths_error_set(err, RTHS_EINPUT,
                                  "output.dofs: DoF %d is beyond the assembly's %d DoFs", dof + 1,
                                  s->n);
        for (int i = 0; !found && i < s->n_phys; i++)
            if (s->phys_dofs[i] == dof) {
                if (i >= RTHS_MAX_SENSED_DOFS)
                    return rths_error_set(err, RTHS_EINPUT,
                                          "output.dofs: physical DoF %d has no sensor (a sensor "
                                          "sample carries the first %d physical DoFs)",
                                          dof + 1, RTHS_MAX_SENSED_DOFS);
                c->out_kind[j] = OUT_SENSOR, c->out_index[j] = i, found = 1;
            }
        for (int d = 0; !found && d < s->n_int; d++)
            if (s->int_dofs[d] == dof)
                c->out_kind[j] = OUT_INTERFACE, c->out_index[j] = d, found = 1;
        for (int i = 0; !found && i < s->n_num; i++)
            if (s->num_dofs[i] == dof) {
                if (setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY)
                    return rths_error_set(err, RTHS_EINPUT,
                                          "output.dofs: numerical DoF %d is not integrated in "
                                          "real time (split.numerical_solver: frequency)",
                                          dof + 1);
                c->out_kind[j] = OUT_STATE, c->out_index[j] = s->n_int + i, found = 1;
            }
        if (!found)
            return rths_error_set(err, RTHS_EINPUT, "output.dofs: DoF %d belongs to no side",
                                  dof + 1);
    }
    return RTHS_OK;
}

int rths_controller_create(const rths_setup *setup, const rths_controller_options *opt,
                           rths_controller **out, rths_error *err) {
    *out = NULL;
    const rths_split *s = &setup->split;
    if (s->n_int < 1 || s->n_int > RTHS_MAX_INTERFACE_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "the controller drives 1 to %d interface DoFs (one actuator each, "
                              "RTHS_MAX_INTERFACE_DOFS in signals.h); this split has %d",
                              RTHS_MAX_INTERFACE_DOFS, s->n_int);
    int rc_sensed = rths_controller_check_sensed_dofs(s, err);
    if (rc_sensed) return rc_sensed;
    int forcing_physical = 0;
    /* base excitation: the numerical model takes -M 1 a_g on its DoFs and the interface's whole
     * share (an interface force acts through the numerical side), the plant its internal DoFs' */
    int base = setup->base_excitation && setup->forcing_shape;
    if (base && s->n_phys > 0 && !opt->plant_applies_forcing)
        return rths_error_set(err, RTHS_EINPUT,
                              "base excitation drives the physical storeys too, and this rig "
                              "does not apply a forcing on the physical side");
    int forcing_interface = -1;
    for (int d = 0; d < s->n_int; d++)
        if (s->int_dofs[d] == setup->forcing_dof) forcing_interface = d;
    if (!base && forcing_interface < 0) {
        int numerical = 0;
        for (int i = 0; i < s->n_num; i++)
            numerical |= s->num_dofs[i] == setup->forcing_dof;
        forcing_physical = !numerical;
        if (forcing_physical && !opt->plant_applies_forcing)
            return rths_error_set(err, RTHS_EINPUT,
                                  "forcing.dof %d is on the physical side; the virtual rig "
                                  "applies the forcing in the numerical substructure (or at the "
                                  "interface)",
                                  setup->forcing_dof + 1);
    }
    if (!(opt->sample_rate_hz > 0))
        return rths_error_set(err, RTHS_EINPUT, "sample rate must be positive");
    rths_controller *c = calloc(1, sizeof *c);
    if (!c) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    c->opt = *opt;
    c->h = 1.0 / opt->sample_rate_hz;
    c->rate = opt->sample_rate_hz;
    c->ramp_step = opt->ramp_time_s > 0 ? c->h / opt->ramp_time_s : 1.0;
    c->cos_step = 1.0;                            /* no frequency yet: rotation by zero */
    harmonic_table_init(&c->tables[0], 1.0, 0.0); /* theta 0 */
    c->nn = s->nn;
    c->nx = 2 * s->nn;
    c->np = s->np;
    c->ni = s->n_int;
    c->n_inputs = s->n_int + 1;
    for (int d = 0; d < c->ni; d++) {
        for (int e = 0; e < c->ni; e++)
            c->m_comp[d + e * MAX_IFACE] = rths_setup_compensation_mass(setup, d, e);
        c->kp[d] = opt->kp_dof_v_per_m[d] > 0 ? opt->kp_dof_v_per_m[d] : opt->kp_v_per_m;
        c->kd[d] = opt->kd_dof_v_s_per_m[d] > 0 ? opt->kd_dof_v_s_per_m[d] : opt->kd_v_s_per_m;
        c->gkp[d] =
            opt->grounding_kp_dof[d] > 0 ? opt->grounding_kp_dof[d] : opt->grounding_kp_n_per_m;
        c->gkd[d] =
            opt->grounding_kd_dof[d] > 0 ? opt->grounding_kd_dof[d] : opt->grounding_kd_n_s_per_m;
    }
    int rc = build_transforms(c, setup, err);
    if (rc) {
        free(c);
        return rc;
    }
    for (int i = 0; i < c->np && i < RTHS_MAX_SENSED_DOFS; i++)
        c->sensed_dof[i] = 1 + (i < s->n_phys ? s->phys_dofs[i] : s->int_dofs[i - s->n_phys]);
    for (int d = 0; d < c->ni; d++)
        c->int_dof[d] = 1 + s->int_dofs[d];
    rc = output_sources(c, setup, err);
    if (rc) {
        free(c);
        return rc;
    }
    c->forcing_index = forcing_interface > 0 ? forcing_interface : 0;
    for (int i = 0; i < s->n_num; i++)
        if (s->num_dofs[i] == setup->forcing_dof) c->forcing_index = s->n_int + i;
    c->host_numerical = setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY;
    if (c->host_numerical && base)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "forcing.type: base with split.numerical_solver: frequency is not "
                            "supported (the host's receptance takes a force on one DoF)");
    if (!rc && !c->host_numerical) rc = numerical_elements(c, setup, err);
    /* a sparse model's reduced stiffness is checked where it is built (krylov_numerical) */
    if (!rc && !c->host_numerical && !setup->sparse)
        rc = numerical_stiffness_definite(s->nn, s->stiffness_num, err);
    if (!rc && !c->host_numerical) rc = build_numerical(c, setup, forcing_physical, base, err);
    if (!rc && !c->host_numerical) rc = grounding_stable(c, s, err);
    if (rc) {
        free(c);
        return rc;
    }
    c->velocity_alpha =
        opt->velocity_cutoff_hz > 0 ? exp(-2 * M_PI * opt->velocity_cutoff_hz * c->h) : 0.0;
    c->harmonics = 1;
    c->target_u = c->glide_u = c->static_u = 1; /* no transition under way */
    c->transition_per_rad =
        opt->transition_periods > 0 ? 1 / (2 * M_PI * opt->transition_periods) : 0;
    rths_spsc_init(&c->ring, c->ring_storage, RING_CAPACITY, sizeof(rths_period));
    atomic_init(&c->dropped, 0);
    *out = c;
    return RTHS_OK;
}

void rths_controller_destroy(rths_controller *c) {
    free(c);
}

static void start_glide(rths_controller *c, double omega_to, double amplitude_to);

void rths_controller_set_forcing(rths_controller *c, double frequency_hz, double amplitude_n) {
    double w = 2 * M_PI * frequency_hz;
    if (c->omega > 0 && c->opt.transition_periods > 0 && c->at_boundary) {
        /* the last sample closed a period: the glide starts from that boundary, and the period
         * it opened is the glide's first */
        start_glide(c, w, amplitude_n);
        c->pending_forcing = 0;
        c->forcing_valid_from_s = c->open_period_start_s;
    } else if (c->omega == 0) {
        /* nothing running yet: start now */
        c->omega = w;
        c->amplitude_n = amplitude_n;
        c->pending_forcing = 0;
        c->open_period_start_s = c->forcing_valid_from_s = c->time_s;
    } else {
        /* frequency and amplitude change together at the next period boundary, so every
         * published period has one forcing; a later call before then replaces this one. The
         * open period ran under the old forcing: periods from one sample past its start on
         * (host's slack h/2, docs/protocol.md) run the new one, and none begins sooner, as a
         * period is at least 4 samples long. */
        if (!c->pending_forcing) c->pending_since_s = c->time_s;
        c->pending_omega = w;
        c->pending_amplitude = amplitude_n;
        c->pending_forcing = 1;
        c->forcing_valid_from_s = c->open_period_start_s + c->h;
    }
}

double rths_controller_forcing_valid_from_s(const rths_controller *c) {
    return c->forcing_valid_from_s;
}

double rths_controller_target_valid_from_s(const rths_controller *c) {
    return c->target_valid_from_s;
}

void rths_controller_set_target(rths_controller *c, int harmonics, const double *a,
                                const double *b) {
    rths_controller_set_target_dofs(c, 1, harmonics, a, b);
}

void rths_controller_set_target_dofs(rths_controller *c, int dofs, int harmonics, const double *a,
                                     const double *b) {
    if (harmonics < 0) harmonics = 0;
    if (harmonics > RTHS_MAX_HARMONICS) harmonics = RTHS_MAX_HARMONICS;
    if (c->opt.transition_periods > 0) {
        /* from what is applied now (a transition under way included) */
        const double s = c->target_u < 1 ? c->target_s : 1.0;
        for (int d = 0; d < MAX_IFACE; d++)
            for (int k = 0; k < RTHS_MAX_HARMONICS; k++) {
                c->from_a[d][k] += s * (c->target_a[d][k] - c->from_a[d][k]);
                c->from_b[d][k] += s * (c->target_b[d][k] - c->from_b[d][k]);
            }
        const int applied =
            c->target_u < 1 && c->from_harmonics > c->harmonics ? c->from_harmonics : c->harmonics;
        c->from_harmonics = applied > harmonics ? applied : harmonics;
        c->target_u = 0;
        c->target_s = c->target_s_rate = 0;
        c->target_waits = c->pending_forcing; /* moves with the forcing's glide */
    }
    /* A target that follows a forcing change still waiting for its boundary, or one that reaches
     * the glide's first period, belongs to that change: its periods are the forcing's, so every
     * site of a multi-site test keeps the same ones (docs/protocol.md, "Which periods follow a
     * change"). In the glide's first period its own transition starts now, the samples it comes
     * late being the host's command gap (a sample or two: the host sends it right behind the
     * forcing). */
    if (c->opt.transition_periods > 0 && c->pending_forcing)
        c->target_valid_from_s = c->forcing_valid_from_s;
    else if (c->glide_first_period) /* the glide may have ended in it (transition_periods < 1) */
        c->target_valid_from_s = c->open_period_start_s;
    else
        c->target_valid_from_s = c->time_s;
    c->harmonics = harmonics;
    for (int d = 0; d < MAX_IFACE; d++)
        for (int k = 0; k < RTHS_MAX_HARMONICS; k++) {
            int given = d < dofs && k < harmonics;
            c->target_a[d][k] = given ? a[d * harmonics + k] : 0;
            c->target_b[d][k] = given ? b[d * harmonics + k] : 0;
        }
}

int rths_controller_interface_dofs(const rths_controller *c) {
    return c->ni;
}

void rths_controller_demands(const rths_controller *c, double *demand_v) {
    memcpy(demand_v, c->demand, sizeof(double) * (size_t)c->ni);
}

void rths_controller_set_feedback(rths_controller *c, int on) {
    c->feedback = on;
}
void rths_controller_arm(rths_controller *c, int armed) {
    c->armed = armed;
}
int rths_controller_armed(const rths_controller *c) {
    return c->armed;
}
rths_rig_fault rths_controller_fault(const rths_controller *c) {
    return c->fault;
}
void rths_controller_trip(rths_controller *c, rths_rig_fault fault) {
    latch_detail(c, fault, RTHS_FAULT_CAUSE_EXTERNAL, 0, 0, 0);
}
void rths_controller_trip_detail(rths_controller *c, const rths_fault_detail *detail) {
    latch_detail(c, (rths_rig_fault)detail->fault, (rths_fault_cause)detail->cause, detail->channel,
                 detail->value, detail->limit);
}
void rths_controller_reset_fault(rths_controller *c) {
    c->fault = RTHS_RIG_OK;
    c->fault_detail = (rths_fault_detail){0};
}
void rths_controller_fault_detail(const rths_controller *c, rths_fault_detail *out) {
    *out = c->fault_detail;
}
void rths_controller_count_sample(rths_controller *c, int late, int clipped_demand,
                                  int saturated_sensor) {
    if (!(c->omega > 0)) return; /* no period is open: nothing to count into */
    c->late_samples += late != 0;
    c->clipped_demand_samples += clipped_demand != 0;
    c->saturated_sensor_samples += saturated_sensor != 0;
}
double rths_controller_time_s(const rths_controller *c) {
    return c->time_s;
}
double rths_controller_frequency_hz(const rths_controller *c) {
    return c->omega / (2 * M_PI);
}
void rths_controller_forcing(const rths_controller *c, double *amplitude_n, double *theta,
                             double *omega_rad_s) {
    *amplitude_n = c->forcing_now;
    *theta = c->theta;
    *omega_rad_s = c->omega;
}
int rths_controller_at_period_boundary(const rths_controller *c) {
    return c->at_boundary;
}
long rths_controller_dropped_periods(const rths_controller *c) {
    return atomic_load(&c->dropped);
}

/* Adds a sample point y at the phase of table t with trapezoid weight w (the sum of its two
 * intervals' dtheta / (2 pi)) to the sums: per sample one product per harmonic and signal, half
 * the work of summing each interval's two ends. */
static void accumulate_point(sums *restrict s, const harmonic_table *restrict t, double w,
                             double y) {
    const double wy = w * y;
    s->mean += 0.5 * wy;
    for (int i = 0; i < 2 * RTHS_MAX_HARMONICS; i++)
        s->ab[i] += wy * t->cs[i];
}

/* a period's sums as its record's coefficients */
static void sums_to_fourier(const sums *s, rths_fourier *f) {
    f->a[0] = s->mean, f->b[0] = 0;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++)
        f->a[k] = s->ab[2 * k - 2], f->b[k] = s->ab[2 * k - 1];
}

static void clear_sums(rths_controller *c) {
    memset(c->acc_phys, 0, sizeof c->acc_phys);
    memset(c->acc_num, 0, sizeof c->acc_num);
    memset(c->acc_force, 0, sizeof c->acc_force);
    memset(c->acc_out, 0, sizeof c->acc_out);
    c->period_samples = 0;
    c->late_samples = c->clipped_demand_samples = c->saturated_sensor_samples = 0;
    c->left_weight = 0; /* the point at theta opens the period */
}

static void publish(rths_controller *c, double end_time) {
    rths_period p;
    memset(&p, 0, sizeof p); /* padding too: records compare bytewise (tests, journals) */
    p.frequency_hz = c->omega / (2 * M_PI);
    p.end_time_s = end_time;
    p.samples = c->period_samples;
    /* at most the period's samples (a demand counted after the step that opened the period
     * belongs to it, and is one of its samples) */
    p.late_samples = c->late_samples < p.samples ? c->late_samples : p.samples;
    p.clipped_demand_samples =
        c->clipped_demand_samples < p.samples ? c->clipped_demand_samples : p.samples;
    p.saturated_sensor_samples =
        c->saturated_sensor_samples < p.samples ? c->saturated_sensor_samples : p.samples;
    p.interface_dofs = c->ni;
    for (int d = 0; d < c->ni; d++) {
        sums_to_fourier(&c->acc_phys[d], &p.phys_dof[d]);
        sums_to_fourier(&c->acc_num[d], &p.num_dof[d]);
        sums_to_fourier(&c->acc_force[d], &p.force_dof[d]);
    }
    p.phys = p.phys_dof[0];
    p.num = p.num_dof[0];
    p.force = p.force_dof[0];
    p.output_dofs = c->n_out;
    for (int j = 0; j < c->n_out; j++)
        sums_to_fourier(&c->acc_out[j], &p.output_dof[j]);
    if (!rths_spsc_push(&c->ring, &p)) atomic_fetch_add(&c->dropped, 1);
    clear_sums(c);
}

int rths_controller_pop_period(rths_controller *c, rths_period *out) {
    return rths_spsc_pop(&c->ring, out);
}

/* theta and its exact cos and sin (the rotation in the step restarts from these) */
static void set_phase(rths_controller *c, double theta) {
    c->theta = theta;
    harmonic_table_init(&c->tables[c->at_theta], cos(theta), sin(theta));
}

/* A forcing change waits for the period boundary, so every published period has one forcing;
 * but an old forcing of very low frequency must not hold a change back for its whole period (at
 * 0.001 Hz: 1000 s, and no period ever closes meanwhile). Past max_pending_s the open period is
 * dropped unpublished and the new forcing starts at phase 0 now. */
static void start_overdue_forcing(rths_controller *c) {
    if (!c->pending_forcing || c->time_s - c->pending_since_s < c->opt.max_pending_s) return;
    c->omega = c->pending_omega;
    c->amplitude_n = c->pending_amplitude;
    c->pending_forcing = 0;
    c->gliding = c->glide_first_period = 0;
    c->target_waits = 0; /* a target change waiting for the glide moves from now */
    set_phase(c, 0.0);
    clear_sums(c);
    c->open_period_start_s = c->time_s;
}

/* The smootherstep: s(0) = 0, s(1) = 1, its first and second derivatives zero at both ends, so
 * a transition's envelope is smooth to the second derivative and its spectrum falls off as the
 * fourth power of frequency times length (docs/method.md, "Smooth transitions"). */
static double smootherstep(double u) {
    return u * u * u * (10 + u * (-15 + 6 * u));
}

/* A glide to omega_to, amplitude_to from the present forcing, begun at the open period's start:
 * its progress is the phase since then, so controllers that glide from the same boundary stay
 * in step sample by sample. A target change waiting for it moves with it. */
static void start_glide(rths_controller *c, double omega_to, double amplitude_to) {
    c->glide_omega_from = c->omega;
    c->glide_amplitude_from = c->amplitude_n;
    c->glide_omega_to = omega_to;
    c->glide_amplitude_to = amplitude_to;
    c->glide_u = c->theta / (2 * M_PI * c->opt.transition_periods);
    c->gliding = 1;
    c->glide_first_period = 1;
    if (c->target_waits) {
        c->target_waits = 0;
        c->target_u = c->glide_u;
    }
}

/* One sample of every transition under way (arithmetic only; the rotor follows the gliding
 * omega in the step). Progress is by phase: the omega this sample advances theta by, over the
 * phase of transition_periods periods (the static term's: one period). */
static void advance_transitions(rths_controller *c) {
    const double per_rad = c->transition_per_rad;
    if (c->gliding) {
        if (c->glide_u >= 1) { /* exactly the new forcing from here on */
            c->omega = c->glide_omega_to;
            c->amplitude_n = c->glide_amplitude_to;
            c->gliding = 0;
        } else {
            const double s = smootherstep(c->glide_u);
            c->omega = c->glide_omega_from + s * (c->glide_omega_to - c->glide_omega_from);
            c->amplitude_n =
                c->glide_amplitude_from + s * (c->glide_amplitude_to - c->glide_amplitude_from);
            c->glide_u += c->omega * c->h * per_rad;
        }
    }
    if (c->target_u < 1 && !c->target_waits) {
        const double du = c->omega * c->h * per_rad, u = c->target_u;
        c->target_s = smootherstep(u);
        c->target_s_rate = 30 * u * u * (1 - u) * (1 - u) * du / c->h;
        c->target_u = u + du;
    }
    if (c->static_u < 1) {
        const double s = smootherstep(c->static_u);
        for (int d = 0; d < c->ni; d++)
            c->static_offset[d] = c->static_from[d] + s * (c->static_to[d] - c->static_from[d]);
        c->static_u += c->omega * c->h / (2 * M_PI);
        if (c->static_u >= 1)
            for (int d = 0; d < c->ni; d++)
                c->static_offset[d] = c->static_to[d];
    }
}

/* x* stays within the displacement limit: a target beyond it (refused by the rigs) or a ramp
 * cannot drive the physical side past the limit before the fault latches. */
static void clamp_target(const rths_controller *c, double *target, double *target_dot) {
    const double limit = c->opt.displacement_limit_m;
    if (fabs(*target) > limit) {
        *target = copysign(limit, *target);
        *target_dot = 0;
    }
}

/* Latches fault f with what caused it (the first fault stays, with its own detail). */
static void latch_detail(rths_controller *c, rths_rig_fault f, rths_fault_cause cause, int channel,
                         double value, double limit) {
    if (c->fault) return;
    c->fault = f;
    c->fault_detail = (rths_fault_detail){.fault = f,
                                          .cause = cause,
                                          .channel = channel,
                                          .value = value,
                                          .limit = limit,
                                          .time_s = c->time_s};
}

/* ramp: up to 1 while armed and healthy, down to 0 otherwise */
static void update_ramp(rths_controller *c) {
    const double dr = c->ramp_step;
    /* clamped inline, not by fmin/fmax: ramp and dr are finite, and libm calls every sample */
    if (c->armed && !c->fault)
        c->ramp = c->ramp + dr < 1.0 ? c->ramp + dr : 1.0;
    else
        c->ramp = c->ramp - dr > 0.0 ? c->ramp - dr : 0.0;
}

typedef struct {
    /* per interface DoF: displacement, acceleration, load-cell force */
    double x[MAX_IFACE], acc[MAX_IFACE], f_lc[MAX_IFACE];
} measured;

/* The sensors against the limits. A non-finite reading latches a fault and is replaced by zero,
 * so the numerical model stays finite. A device that fills only the scalar interface readings
 * (n_interface 0) serves the first interface DoF. */
/* Through the transforms: raw holds the lasers' displacements, the actuators' accelerations and
 * load-cell forces; m gets the interface DoFs' displacements, accelerations and efforts. */
static void untransform(const rths_controller *c, const measured *raw, measured *m) {
    for (int d = 0; d < c->ni; d++) {
        double x = 0, acc = 0, f = 0;
        for (int e = 0; e < c->ni; e++) {
            x += c->s_inv[d + e * MAX_IFACE] * raw->x[e];
            acc += c->t_acc[d + e * MAX_IFACE] * raw->acc[e];
            f += c->t_eff[d + e * MAX_IFACE] * raw->f_lc[e];
        }
        m->x[d] = x, m->acc[d] = acc, m->f_lc[d] = f;
    }
}

static void read_sensors(rths_controller *c, const rths_sensor_sample *in, measured *m) {
    int finite = 1;
    for (int d = 0; d < c->ni; d++) {
        int arrays = in->n_interface > d;
        m->x[d] = in->displacement_m[c->np - c->ni + d];
        m->acc[d] = arrays   ? in->interface_acceleration_dof_m_s2[d]
                    : d == 0 ? in->interface_acceleration_m_s2
                             : NAN;
        m->f_lc[d] = arrays ? in->interface_force_dof_n[d] : d == 0 ? in->interface_force_n : NAN;
        /* the first non-finite reading names the fault (the laser's below) */
        if (!isfinite(m->acc[d]))
            latch_detail(c, RTHS_RIG_FAULT_NONFINITE, RTHS_FAULT_CAUSE_NONFINITE_ACCELEROMETER,
                         d + 1, m->acc[d], 0);
        if (!isfinite(m->f_lc[d]))
            latch_detail(c, RTHS_RIG_FAULT_NONFINITE, RTHS_FAULT_CAUSE_NONFINITE_LOAD_CELL, d + 1,
                         m->f_lc[d], 0);
        finite &= isfinite(m->x[d]) && isfinite(m->acc[d]) && isfinite(m->f_lc[d]);
    }
    for (int i = 0; i < in->n && i < RTHS_MAX_SENSED_DOFS; i++) {
        const double x = in->displacement_m[i];
        if (!isfinite(x))
            latch_detail(c, RTHS_RIG_FAULT_NONFINITE, RTHS_FAULT_CAUSE_NONFINITE_LASER,
                         c->sensed_dof[i], x, 0);
        finite &= isfinite(x);
        if (fabs(x) > c->opt.displacement_limit_m)
            latch_detail(c, RTHS_RIG_FAULT_DISPLACEMENT, RTHS_FAULT_CAUSE_DISPLACEMENT_LIMIT,
                         c->sensed_dof[i], x, c->opt.displacement_limit_m);
    }
    if (!finite) {
        latch_detail(c, RTHS_RIG_FAULT_NONFINITE, RTHS_FAULT_CAUSE_NONFINITE_LASER, 0, NAN, 0);
        memset(m, 0, sizeof *m);
        c->ramp = 0;
    }
    /* the force limit is each load cell's */
    for (int d = 0; d < c->ni; d++)
        if (fabs(m->f_lc[d]) > c->opt.force_limit_n)
            latch_detail(c, RTHS_RIG_FAULT_FORCE, RTHS_FAULT_CAUSE_FORCE_LIMIT, d + 1, m->f_lc[d],
                         c->opt.force_limit_n);
    if (c->transformed) {
        measured raw = *m;
        untransform(c, &raw, m);
    }
    for (int d = 0; d < c->ni; d++) {
        /* velocity of the physical interface: filtered backward difference */
        double v_raw = c->have_prev ? (m->x[d] - c->x_prev[d]) * c->rate : 0.0;
        c->v_est[d] = c->velocity_alpha * c->v_est[d] + (1 - c->velocity_alpha) * v_raw;
        c->x_prev[d] = m->x[d];
    }
    c->have_prev = 1;
}

/* Grounding control F_ctrl on interface DoF d. It compares like with like, the last measured x
 * with the last xi and both velocities by the same backward difference, so it vanishes exactly
 * when the interface matches (erratum 8) and adds no spurious stiffness or damping to the
 * converged response. */
static double grounding_force(rths_controller *c, int d, double x) {
    const double xi = c->z[d];
    double x_last = c->grounding_have ? c->x_last[d] : x;
    double xi_last_prev = c->grounding_have ? c->xi_last_prev[d] : xi;
    double x_last_prev = c->grounding_have ? c->x_last_prev[d] : x_last;
    double f_ctrl = c->gkp[d] * (x_last - xi) +
                    c->gkd[d] * ((x_last - x_last_prev) - (xi - xi_last_prev)) * c->rate;
    c->x_last_prev[d] = x_last;
    c->x_last[d] = x;
    c->xi_last_prev[d] = xi;
    return f_ctrl;
}

/* An element's coordinate (deformation or rate) in state z. */
static inline double nl_coordinate(const nl_state *ns, const double *z) {
    return z[ns->off + ns->i] - (ns->j >= 0 ? z[ns->off + ns->j] : 0.0);
}

/* The force of a kink element over a sample whose coordinate runs linearly from y0 to y1, as the
 * first-order hold the exact FOH discretisation takes: the straight line with the profile's own
 * mean and first moment (its L2 projection), endpoint values *a, *b and db/dy1 in *db, da/dy1 in
 * *da. Without a crossing the profile is that line; with one (the kink located inside the
 * sample at s* = y0 / (y0 - y1)) its moments are those of the triangle on the contact side, and
 * what the line misses is the profile's second moment against the sample's curvature of
 * e^{A (h - s)}, O((omega h)^2) of one sample's kink. */
static void kink_hold(double k, double y0, double y1, double *a, double *b, double *da,
                      double *db) {
    if (y0 <= 0 && y1 <= 0) {
        *a = k * y0, *b = k * y1, *da = 0, *db = k;
        return;
    }
    if (y0 >= 0 && y1 >= 0) {
        *a = *b = *da = *db = 0;
        return;
    }
    const double inv = 1.0 / (y0 - y1), sc = y0 * inv, ds = y0 * inv * inv;
    double m0, m1, dm0, dm1; /* int_0^1 g ds, int_0^1 s g ds and their y1-derivatives */
    if (y0 < 0) {            /* in contact until s* */
        m0 = 0.5 * k * y0 * sc;
        m1 = k * y0 * sc * sc / 6;
        dm0 = 0.5 * k * y0 * ds;
        dm1 = k * y0 * sc * ds / 3;
    } else { /* in contact from s* */
        m0 = 0.5 * k * (y0 + y1) - 0.5 * k * y0 * sc;
        m1 = k * (y0 / 6 + y1 / 3) - k * y0 * sc * sc / 6;
        dm0 = 0.5 * k - 0.5 * k * y0 * ds;
        dm1 = k / 3 - k * y0 * sc * ds / 3;
    }
    *a = 4 * m0 - 6 * m1, *b = 6 * m1 - 2 * m0;
    *da = 4 * dm0 - 6 * dm1, *db = 6 * dm1 - 2 * dm0;
}

/* Element e's hold over the sample: endpoint forces (a, b) and their y1-derivatives. A kink under
 * the FOH by its moments; otherwise the endpoint forces themselves (the FOH's trapezoid: implicit
 * trapezoidal in the force, second order). */
static void element_hold(const rths_controller *c, const nl_state *ns, double y0, double y1,
                         double *a, double *b, double *da, double *db) {
    if (ns->kink && c->nl_foh) {
        kink_hold(ns->el.k, y0 + ns->el.clearance_m, y1 + ns->el.clearance_m, a, b, da, db);
        return;
    }
    *a = rths_nl_force(&ns->el, y0, NULL);
    *b = rths_nl_force(&ns->el, y1, db);
    *da = 0;
}

/* Solves the n x n system J x = r in place (Gaussian elimination with partial pivoting, n <=
 * MAX_NL, leading dimension MAX_NL): no LAPACK per sample. Returns 0, -1 when singular. */
static int small_solve(int n, double *J, double *r) {
    for (int col = 0; col < n; col++) {
        int piv = col;
        for (int i = col + 1; i < n; i++)
            if (fabs(J[i + col * MAX_NL]) > fabs(J[piv + col * MAX_NL])) piv = i;
        if (!(fabs(J[piv + col * MAX_NL]) > 0)) return -1;
        if (piv != col) {
            for (int j = 0; j < n; j++) {
                double t = J[col + j * MAX_NL];
                J[col + j * MAX_NL] = J[piv + j * MAX_NL];
                J[piv + j * MAX_NL] = t;
            }
            double t = r[col];
            r[col] = r[piv];
            r[piv] = t;
        }
        for (int i = col + 1; i < n; i++) {
            double f = J[i + col * MAX_NL] / J[col + col * MAX_NL];
            for (int j = col; j < n; j++)
                J[i + j * MAX_NL] -= f * J[col + j * MAX_NL];
            r[i] -= f * r[col];
        }
    }
    for (int i = n - 1; i >= 0; i--) {
        double sum = r[i];
        for (int j = i + 1; j < n; j++)
            sum -= J[i + j * MAX_NL] * r[j];
        r[i] = sum / J[i + i * MAX_NL];
    }
    return 0;
}

/* The nonlinear elements' contribution to the sample's end state: next holds the linear step
 * from z (the state at the sample's start); the elements' end coordinates y1 solve
 * y1 = C next + S_prev a(y0, y1) + S_curr b(y0, y1) by at most NL_NEWTON_STEPS Newton steps
 * from the explicit guess (end forces = start forces), then next += bg_prev a + bg_curr b. */
static void advance_nonlinear(rths_controller *c, double *next) {
    const int m = c->n_nl, nx = c->nx;
    double y0[MAX_NL], yl[MAX_NL], y1[MAX_NL], a[MAX_NL], b[MAX_NL], da[MAX_NL], db[MAX_NL];
    double J[MAX_NL * MAX_NL], r[MAX_NL];
    double scale = 0;
    for (int e = 0; e < m; e++) {
        y0[e] = nl_coordinate(&c->nl[e], c->z);
        yl[e] = nl_coordinate(&c->nl[e], next);
        a[e] = b[e] = rths_nl_force(&c->nl[e].el, y0[e], NULL);
        scale = fmax(scale, fmax(fabs(y0[e]), fabs(yl[e])));
    }
    for (int e = 0; e < m; e++) {
        y1[e] = yl[e];
        for (int f = 0; f < m; f++)
            y1[e] += (c->sg_prev[e + f * MAX_NL] + c->sg_curr[e + f * MAX_NL]) * a[f];
    }
    const double tol = 1e-13 * scale;
    int steps = 0;
    for (; steps < NL_NEWTON_STEPS; steps++) {
        for (int e = 0; e < m; e++)
            element_hold(c, &c->nl[e], y0[e], y1[e], &a[e], &b[e], &da[e], &db[e]);
        double worst = 0;
        for (int e = 0; e < m; e++) {
            double sum = yl[e] - y1[e];
            for (int f = 0; f < m; f++) {
                sum += c->sg_prev[e + f * MAX_NL] * a[f] + c->sg_curr[e + f * MAX_NL] * b[f];
                J[e + f * MAX_NL] =
                    c->sg_prev[e + f * MAX_NL] * da[f] + c->sg_curr[e + f * MAX_NL] * db[f];
            }
            J[e + e * MAX_NL] -= 1.0;
            r[e] = -sum;
            worst = fmax(worst, fabs(sum));
        }
        if (worst <= tol) break;
        if (small_solve(m, J, r)) break;
        for (int e = 0; e < m; e++)
            y1[e] += r[e];
    }
    if (steps == NL_NEWTON_STEPS)
        for (int e = 0; e < m; e++) /* the forces of the last iterate */
            element_hold(c, &c->nl[e], y0[e], y1[e], &a[e], &b[e], &da[e], &db[e]);
    if (steps > c->nl_newton_max) c->nl_newton_max = steps;
    for (int f = 0; f < m; f++) {
        const double *bp = c->bg_prev + (size_t)f * (size_t)nx,
                     *bc = c->bg_curr + (size_t)f * (size_t)nx;
        for (int i = 0; i < nx; i++)
            next[i] += bp[i] * a[f] + bc[i] * b[f];
    }
}

/* One step of the discretised numerical substructure under inputs u; its interface
 * displacements and velocities after the step. */
static void advance_numerical(rths_controller *c, const double *u, double *xi, double *xi_dot) {
    const int nx = c->nx, n_in = c->n_inputs;
    /* row by row, each sum in a register: in c the partial sums would alias ad and z and go
     * through memory on every term (the step's largest cost at the seed's size). The order of
     * the terms is that of a plain product, z's columns first, then the held inputs. */
    double next[MAX_STATE];
    const double *restrict ad = c->ad, *restrict z = c->z, *restrict up = c->u_prev,
                           *restrict bp = c->b_prev, *restrict bc = c->b_curr;
    for (int i = 0; i < nx; i++) {
        double sum = 0;
        for (int j = 0; j < nx; j++)
            sum += ad[i + (size_t)j * (size_t)nx] * z[j];
        for (int j = 0; j < n_in; j++)
            sum += bp[i + (size_t)j * (size_t)nx] * up[j] + bc[i + (size_t)j * (size_t)nx] * u[j];
        next[i] = sum;
    }
    if (c->has_static)
        for (int i = 0; i < nx; i++)
            next[i] += c->static_step[i];
    if (c->n_nl) advance_nonlinear(c, next);
    /* element by element: a handful of doubles, where a libc call would cost more than the copy */
    for (int i = 0; i < nx; i++)
        c->z[i] = next[i];
    for (int j = 0; j < n_in; j++)
        c->u_prev[j] = u[j];
    int finite = 1, first_bad = 0;
    for (int d = 0; d < c->ni; d++) {
        xi[d] = c->z[d];
        xi_dot[d] = c->z[c->nn + d];
        if (finite && !isfinite(xi[d])) first_bad = d;
        finite &= isfinite(xi[d]);
    }
    if (!finite) {
        latch_detail(c, RTHS_RIG_FAULT_NONFINITE, RTHS_FAULT_CAUSE_NONFINITE_NUMERICAL,
                     c->int_dof[first_bad], xi[first_bad], 0);
        memset(c->z, 0, sizeof c->z);
        memset(c->u_prev, 0, sizeof c->u_prev);
        for (int d = 0; d < c->ni; d++)
            xi[d] = xi_dot[d] = 0;
    }
}

/* x*(theta1) of interface DoF d and its rate: the periodic target (ramped, plus the tracked
 * static term, clamped to the stroke) or, in feedback mode, the numerical interface itself. */
static void control_target(const rths_controller *c, int d, const harmonic_table *he, double xi,
                           double xi_dot, double *target, double *target_dot) {
    if (c->feedback) {
        *target = xi;
        *target_dot = xi_dot;
        return;
    }
    double t = 0, t_dot = 0; /* at theta1: cos/sin of k theta1 from the sample's ends */
    if (c->target_u < 1) {
        const double s = c->target_s, s_rate = c->target_s_rate;
        for (int k = 1; k <= c->from_harmonics; k++) {
            const double ck = he->cs[2 * k - 2], sk = he->cs[2 * k - 1];
            const double da = c->target_a[d][k - 1] - c->from_a[d][k - 1],
                         db = c->target_b[d][k - 1] - c->from_b[d][k - 1];
            const double a = c->from_a[d][k - 1] + s * da, b = c->from_b[d][k - 1] + s * db;
            t += a * ck + b * sk;
            t_dot += k * c->omega * (-a * sk + b * ck) + s_rate * (da * ck + db * sk);
        }
    } else {
        for (int k = 1; k <= c->harmonics; k++) {
            const double ck = he->cs[2 * k - 2], sk = he->cs[2 * k - 1];
            t += c->target_a[d][k - 1] * ck + c->target_b[d][k - 1] * sk;
            t_dot += k * c->omega * (-c->target_a[d][k - 1] * sk + c->target_b[d][k - 1] * ck);
        }
    }
    t *= c->ramp;
    t_dot *= c->ramp;
    /* The static term follows the physical side's own mean (last whole period), so the actuator
     * carries no static load: the preload alone sets the static point, as in the true assembly,
     * and the numerical interface's mean follows through the grounding. */
    if (c->opt.track_static) t += c->static_offset[d];
    clamp_target(c, &t, &t_dot);
    *target = t;
    *target_dot = t_dot;
}

/* Actuator a's demand against the limits: non-finite or beyond demand_v latches; after a trip
 * it ramps to zero. */
static double limited_demand(rths_controller *c, int a, double demand) {
    if (!isfinite(demand)) {
        latch_detail(c, RTHS_RIG_FAULT_NONFINITE, RTHS_FAULT_CAUSE_NONFINITE_DEMAND, a + 1, demand,
                     0);
        demand = 0;
    }
    if (fabs(demand) > c->opt.demand_limit_v)
        latch_detail(c, RTHS_RIG_FAULT_DEMAND, RTHS_FAULT_CAUSE_DEMAND_LIMIT, a + 1, demand,
                     c->opt.demand_limit_v);
    if (c->fault) demand *= c->ramp; /* ramps to zero after a trip, then holds zero */
    return demand;
}

static double pd_demand(rths_controller *c, int d, double target, double target_dot, double x) {
    return limited_demand(c, d, c->kp[d] * (target - x) + c->kd[d] * (target_dot - c->v_est[d]));
}

/* The actuators' demands from every interface DoF's error through the gain matrices. */
static void transformed_demands(rths_controller *c, const double *target, const double *target_dot,
                                const double *x) {
    double e[MAX_IFACE], e_dot[MAX_IFACE];
    for (int d = 0; d < c->ni; d++) {
        e[d] = target[d] - x[d];
        e_dot[d] = target_dot[d] - c->v_est[d];
    }
    for (int a = 0; a < c->ni; a++) {
        double demand = 0;
        for (int d = 0; d < c->ni; d++)
            demand += c->gp[a + d * MAX_IFACE] * e[d] + c->gd[a + d * MAX_IFACE] * e_dot[d];
        c->demand[a] = limited_demand(c, a, demand);
    }
}

/* The three signals (physical, numerical, force) of every interface DoF at the phase of table t
 * into the sums with weight w. */
static void accumulate_signals(rths_controller *c, const harmonic_table *t, double w,
                               const double *y, const double *y_out) {
    for (int d = 0; d < c->ni; d++) {
        accumulate_point(&c->acc_phys[d], t, w, y[3 * d]);
        accumulate_point(&c->acc_num[d], t, w, y[3 * d + 1]);
        accumulate_point(&c->acc_force[d], t, w, y[3 * d + 2]);
    }
    for (int j = 0; j < c->n_out; j++)
        accumulate_point(&c->acc_out[j], t, w, y_out[j]);
}

/* Fourier sums over whole periods (trapezoid in theta, exact period ends by interpolation); at
 * theta = 2 pi the period is published and a pending forcing change takes over. The sample spans
 * [theta0, theta1], cos/sin of k theta1 in the table other than tables[at_theta]. The point at
 * theta0 (y_prev) enters the sums now, with the weight of both its intervals; the point at theta1
 * waits for its next one. */
static void update_fourier(rths_controller *c, double theta0, double theta1, const double *y,
                           const double *y_out) {
    if (!(c->omega > 0)) return;
    const double two_pi = 2 * M_PI;
    if (theta1 < two_pi) {
        const double w = (theta1 - theta0) / two_pi;
        accumulate_signals(c, &c->tables[c->at_theta], c->left_weight + w, c->y_prev,
                           c->y_out_prev);
        c->left_weight = w;
        c->period_samples++;
        c->theta = theta1;
        c->at_theta = !c->at_theta; /* theta1's table becomes theta's */
        return;
    }
    /* the period ends at theta = 2 pi exactly (cos 1, sin 0), at yb by interpolation */
    harmonic_table at_zero;
    harmonic_table_init(&at_zero, 1.0, 0.0);
    const double alpha = (two_pi - theta0) / (theta1 - theta0), w_end = (two_pi - theta0) / two_pi;
    double yb[3 * MAX_IFACE] = {0}, yb_out[MAX_OUT];
    for (int i = 0; i < 3 * c->ni; i++)
        yb[i] = c->y_prev[i] + alpha * (y[i] - c->y_prev[i]);
    for (int j = 0; j < c->n_out; j++)
        yb_out[j] = c->y_out_prev[j] + alpha * (y_out[j] - c->y_out_prev[j]);
    accumulate_signals(c, &c->tables[c->at_theta], c->left_weight + w_end, c->y_prev,
                       c->y_out_prev);
    accumulate_signals(c, &at_zero, w_end, yb, yb_out);
    c->period_samples++;
    if (c->opt.transition_periods > 0) {
        for (int d = 0; d < c->ni; d++) {
            c->static_from[d] = c->static_offset[d];
            c->static_to[d] = c->acc_phys[d].mean;
        }
        c->static_u = 0;
    } else {
        for (int d = 0; d < c->ni; d++)
            c->static_offset[d] = c->acc_phys[d].mean;
    }
    c->open_period_start_s = c->time_s - (1 - alpha) * c->h;
    publish(c, c->open_period_start_s);
    c->glide_first_period = 0;
    const int glide = c->pending_forcing && c->opt.transition_periods > 0;
    if (c->pending_forcing && !glide) {
        c->omega = c->pending_omega;
        c->amplitude_n = c->pending_amplitude;
        c->pending_forcing = 0;
    }
    /* the next period opens at theta = 0 with yb; the point at rest = theta1 - 2 pi waits */
    const double rest = theta1 - two_pi;
    accumulate_signals(c, &at_zero, rest / two_pi, yb, yb_out);
    set_phase(c, rest);
    if (glide) {
        start_glide(c, c->pending_omega, c->pending_amplitude);
        c->pending_forcing = 0;
    }
    c->left_weight = rest / two_pi;
    c->at_boundary = 1;
}

/* Inputs of the numerical model: on interface DoF d F_num = F_comp - F_LC + F_ctrl with
 * F_comp = (p M_int x''_measured)_d; then the forcing. */
static void numerical_forces(rths_controller *c, const measured *m, double cos1, double *u,
                             double *f_interface) {
    for (int d = 0; d < c->ni; d++) {
        double f_comp = 0;
        for (int e = 0; e < c->ni; e++)
            f_comp += c->m_comp[d + e * MAX_IFACE] * m->acc[e];
        f_interface[d] = f_comp - m->f_lc[d];
        u[d] = f_interface[d] + grounding_force(c, d, m->x[d]);
    }
    c->grounding_have = 1;
    u[c->ni] = c->forcing_now * cos1;
}

/* Output DoF j's displacement this sample (after the numerical step: the state at theta1, as the
 * interface's xi). A sensor the device does not fill reads NaN, which the host reports as such. */
static double output_displacement(const rths_controller *c, int j, const rths_sensor_sample *in,
                                  const measured *m) {
    const int i = c->out_index[j];
    switch (c->out_kind[j]) {
    case OUT_SENSOR:
        return i < in->n ? in->displacement_m[i] : NAN;
    case OUT_INTERFACE:
        return m->x[i];
    case OUT_STATE:
        return c->host_numerical ? NAN : c->z[i];
    default: {
        double x = 0;
        for (int k = 0; k < c->nn; k++)
            x += c->out_row[j][k] * c->z[k];
        return x;
    }
    }
}

double rths_controller_step(rths_controller *c, const rths_sensor_sample *in,
                            rths_controller_output *out) {
    update_ramp(c);
    measured m;
    read_sensors(c, in, &m);
    start_overdue_forcing(c);
    advance_transitions(c);
    /* phase of this sample: both ends of its interval, the end by one rotation */
    const double theta0 = c->theta, theta1 = theta0 + c->omega * c->h;
    if (c->omega !=
        c->rotor_omega) { /* a new frequency: once per change (each sample of a glide) */
        c->rotor_omega = c->omega;
        c->cos_step = cos(c->omega * c->h), c->sin_step = sin(c->omega * c->h);
    }
    const double cos0 = c->tables[c->at_theta].cs[0], sin0 = c->tables[c->at_theta].cs[1];
    const double cos1 = cos0 * c->cos_step - sin0 * c->sin_step,
                 sin1 = sin0 * c->cos_step + cos0 * c->sin_step;
    /* a sample past the period boundary belongs to the next period: its forcing amplitude */
    if (c->pending_forcing && c->omega > 0 && theta1 >= 2 * M_PI &&
        !(c->opt.transition_periods > 0))
        c->amplitude_n = c->pending_amplitude;
    c->forcing_now = c->ramp * c->amplitude_n;
    double u[MAX_INPUTS], f_interface[MAX_IFACE];
    numerical_forces(c, &m, cos1, u, f_interface);
    double xi[MAX_IFACE] = {0}, xi_dot[MAX_IFACE] = {0}, target[MAX_IFACE], target_dot[MAX_IFACE];
    if (!c->host_numerical) advance_numerical(c, u, xi, xi_dot);
    double y[3 * MAX_IFACE];
    /* cos/sin of k theta1, for the targets and the Fourier sums */
    harmonic_table *at_end = &c->tables[!c->at_theta];
    harmonic_table_init(at_end, cos1, sin1);
    for (int d = 0; d < c->ni; d++)
        control_target(c, d, at_end, xi[d], xi_dot[d], &target[d], &target_dot[d]);
    if (c->transformed) transformed_demands(c, target, target_dot, m.x);
    for (int d = 0; d < c->ni; d++) {
        if (!c->transformed) c->demand[d] = pd_demand(c, d, target[d], target_dot[d], m.x[d]);
        /* numerical substructure on the host: its interface force goes where xi would */
        y[3 * d] = m.x[d];
        y[3 * d + 1] = c->host_numerical ? f_interface[d] : xi[d];
        y[3 * d + 2] = m.f_lc[d];
    }
    double y_out[MAX_OUT];
    for (int j = 0; j < c->n_out; j++)
        y_out[j] = output_displacement(c, j, in, &m);
    c->at_boundary = 0;
    c->time_s += c->h;
    update_fourier(c, theta0, theta1, y, y_out);
    for (int i = 0; i < 3 * c->ni; i++)
        c->y_prev[i] = y[i];
    for (int j = 0; j < c->n_out; j++)
        c->y_out_prev[j] = y_out[j];
    if (out) {
        out->time_s = c->time_s;
        out->demand_v = c->demand[0];
        out->target_m = target[0];
        out->x_phys_m = m.x[0];
        out->x_num_m = xi[0];
        out->force_n = m.f_lc[0];
        out->dofs = c->ni;
        for (int d = 0; d < c->ni; d++) {
            out->x_phys_dof_m[d] = m.x[d];
            out->x_num_dof_m[d] = xi[d];
            out->target_dof_m[d] = target[d];
            out->force_dof_n[d] = m.f_lc[d];
            out->demand_dof_v[d] = c->demand[d];
        }
    }
    return c->demand[0];
}
