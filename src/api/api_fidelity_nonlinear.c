/* rths fidelity with nonlinear elements (docs/method.md, "Integration fidelity with nonlinear
 * elements"): the real-time step's steady-state error against the harmonic-balance truth.
 *
 * The linear fidelity (fidelity.h) keeps the physical side exact and discretises the numerical
 * side only, in the frequency domain. With nonlinear elements there is no transfer function: the
 * step itself is run, as a pure simulation of the whole assembly (every DoF on the numerical side,
 * every element numerical, no physical side to measure: the sensors read zero, the grounding
 * control and the inertial compensation are off), so what it shows is the step's own
 * discretisation of the linear part and the elements, at the configured sample rate and scheme. */
#include "api/api_fidelity_nonlinear.h"

#include "rths/harmonic_balance.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* the dense harmonic balance's unknowns n (2 H + 1) at most (LU of this size per Newton step) */
#define MAX_HB_UNKNOWNS 2500
/* harmonics of the least-squares fit of the step's samples over their forcing phase */
#define FIT_HARMONICS 16
#define FIT_SIZE (2 * FIT_HARMONICS + 1)
/* periods per fit window; settled when three consecutive windows' fundamentals agree to this
 * (two could by chance, where the decaying free response beats against the forced one) */
#define WINDOW_PERIODS 10
#define SETTLED_RELATIVE 1e-8
#define SETTLED_RESIDUAL 1e-7
/* simulated time per frequency at most */
#define MAX_SIMULATED_S 600.0

int rths_fidelity_nl_applies(const rths_setup *setup, const char **why) {
    const int n = setup->assembly.n, iface = setup->split.int_dofs[0];
    if (setup->n_nonlinear == 0) {
        *why = "no nonlinear elements";
        return 0;
    }
    if (setup->static_force && setup->static_force[iface] != 0) {
        *why = "a static force on the interface DoF (the simulation carries static forces on "
               "internal DoFs only)";
        return 0;
    }
    if ((long)n * (2 * RTHS_FIDELITY_NL_HARMONICS + 1) > MAX_HB_UNKNOWNS) {
        *why = "too many DoFs for the dense harmonic-balance truth";
        return 0;
    }
    *why = NULL;
    return 1;
}

/* The assembly as one numerical substructure: interface DoF (the split's first) first, then every
 * other DoF; a one-DoF physical side of zero matrices that nothing measures. */
static int all_numerical_split(const rths_setup *setup, rths_split *s, rths_error *err) {
    const rths_assembly *a = &setup->assembly;
    const int n = a->n, iface = setup->split.int_dofs[0];
    memset(s, 0, sizeof *s);
    s->n = n, s->n_phys = 0, s->n_int = 1, s->n_num = n - 1, s->np = 1, s->nn = n;
    s->mass_ratio = 1.0;
    s->phys_dofs = malloc(sizeof(int));
    s->int_dofs = malloc(sizeof(int));
    s->num_dofs = malloc(sizeof(int) * (size_t)(n > 1 ? n - 1 : 1));
    s->mass_ratios = malloc(sizeof(double));
    s->mass_phys = rths_mat_new(1, 1);
    s->damping_phys = rths_mat_new(1, 1);
    s->stiffness_phys = rths_mat_new(1, 1);
    s->mass_num = rths_mat_new(n, n);
    s->damping_num = rths_mat_new(n, n);
    s->stiffness_num = rths_mat_new(n, n);
    if (!s->phys_dofs || !s->int_dofs || !s->num_dofs || !s->mass_ratios || !s->mass_phys ||
        !s->damping_phys || !s->stiffness_phys || !s->mass_num || !s->damping_num ||
        !s->stiffness_num) {
        rths_split_free(s);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    s->mass_ratios[0] = 1.0;
    s->int_dofs[0] = iface;
    int *order = malloc(sizeof(int) * (size_t)n);
    if (!order) {
        rths_split_free(s);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    order[0] = iface;
    for (int i = 0, k = 0; i < n; i++)
        if (i != iface) s->num_dofs[k] = i, order[1 + k++] = i;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            RTHS_AT(s->mass_num, n, i, j) = RTHS_AT(a->mass, n, order[i], order[j]);
            RTHS_AT(s->damping_num, n, i, j) = RTHS_AT(a->damping, n, order[i], order[j]);
            RTHS_AT(s->stiffness_num, n, i, j) = RTHS_AT(a->stiffness, n, order[i], order[j]);
        }
    free(order);
    return RTHS_OK;
}

/* The fundamental's amplitude of samples x(theta) by least squares over harmonics 0..FIT_HARMONICS
 * of the forcing phase: the step's steady state is a function of the phase (sampled at phases
 * that do not repeat unless the period is a whole number of samples), and the fit takes its
 * coefficients without the end-of-period error of a one-period quadrature. */
typedef struct {
    double gram[FIT_SIZE * FIT_SIZE], rhs[FIT_SIZE];
} fit;

static void fit_add(fit *f, double theta, double x) {
    double phi[FIT_SIZE];
    phi[0] = 1.0;
    const double c1 = cos(theta), s1 = sin(theta);
    double c = 1.0, s = 0.0;
    for (int k = 1; k <= FIT_HARMONICS; k++) {
        const double ck = c * c1 - s * s1, sk = s * c1 + c * s1;
        c = ck, s = sk;
        phi[2 * k - 1] = c, phi[2 * k] = s;
    }
    for (int j = 0; j < FIT_SIZE; j++) {
        f->rhs[j] += x * phi[j];
        for (int i = 0; i <= j; i++)
            f->gram[i + j * FIT_SIZE] += phi[i] * phi[j];
    }
}

/* The fundamental's amplitude; *residual_rms the root mean square of what the fit leaves of the
 * window's samples (theta, x; count): the free response still decaying, at the structure's own
 * frequencies, which no harmonic of the forcing takes. */
static double fit_fundamental(fit *f, const double *theta, const double *x, long count,
                              double *residual_rms) {
    for (int j = 0; j < FIT_SIZE; j++)
        for (int i = j + 1; i < FIT_SIZE; i++)
            f->gram[i + j * FIT_SIZE] = f->gram[j + i * FIT_SIZE];
    *residual_rms = NAN;
    if (rths_mat_solve(FIT_SIZE, 1, f->gram, f->rhs)) return NAN;
    double sum = 0;
    for (long i = 0; i < count; i++) {
        double y = f->rhs[0];
        for (int k = 1; k <= FIT_HARMONICS; k++)
            y += f->rhs[2 * k - 1] * cos(k * theta[i]) + f->rhs[2 * k] * sin(k * theta[i]);
        sum += (x[i] - y) * (x[i] - y);
    }
    *residual_rms = sqrt(sum / (double)count);
    return hypot(f->rhs[1], f->rhs[2]);
}

/* The step at hz from the controller's present state until three fit windows' fundamentals agree
 * and the fit's residual (the free response) is below SETTLED_RESIDUAL of the amplitude, or has
 * stopped falling (the harmonics above FIT_HARMONICS a kink leaves, not a transient). */
static int settle(rths_controller *c, double hz, double rate_hz, rths_fidelity_nl_point *p) {
    rths_sensor_sample in = {.n = 1, .n_interface = 1};
    rths_controller_output out;
    const long window = (long)ceil(WINDOW_PERIODS * rate_hz / hz);
    const long limit = (long)(MAX_SIMULATED_S * rate_hz);
    double previous = NAN, amplitude = NAN, residual = NAN, previous_residual = NAN;
    long k = 0;
    int agreeing = 0;
    double *theta_s = malloc(sizeof *theta_s * (size_t)window),
           *x_s = malloc(sizeof *x_s * (size_t)window);
    p->settled = 0;
    if (!theta_s || !x_s) {
        free(theta_s), free(x_s);
        return -1;
    }
    while (k < limit) {
        fit f;
        memset(&f, 0, sizeof f);
        for (long i = 0; i < window; i++, k++) {
            rths_controller_step(c, &in, &out);
            double amp, theta, omega;
            rths_controller_forcing(c, &amp, &theta, &omega);
            fit_add(&f, theta, out.x_num_m);
            theta_s[i] = theta, x_s[i] = out.x_num_m;
            rths_period sink;
            while (rths_controller_pop_period(c, &sink)) {
            }
        }
        amplitude = fit_fundamental(&f, theta_s, x_s, window, &residual);
        agreeing =
            fabs(amplitude - previous) <= SETTLED_RELATIVE * fabs(amplitude) ? agreeing + 1 : 0;
        int quiet = residual <= SETTLED_RESIDUAL * amplitude ||
                    fabs(residual - previous_residual) <= 0.01 * residual;
        previous_residual = residual;
        if (agreeing >= 2 && quiet) {
            p->settled = 1;
            break;
        }
        previous = amplitude;
    }
    p->step_amplitude_m = amplitude;
    p->settled_s = (double)k / rate_hz;
    free(theta_s), free(x_s);
    return 0;
}

/* The truth at omega: harmonic balance at H and H/2 harmonics from coef (the previous frequency's
 * solution, H harmonics), which it updates. */
static int truth(const rths_setup *setup, double omega, double *coef, double *coef_half,
                 rths_fidelity_nl_point *p, rths_error *err) {
    const int n = setup->assembly.n, dof = setup->split.int_dofs[0];
    rths_hb_options o;
    rths_hb_defaults(&o);
    o.harmonics = RTHS_FIDELITY_NL_HARMONICS;
    o.samples = RTHS_FIDELITY_NL_SAMPLES;
    int its;
    int rc = rths_hb_solve(&setup->assembly, setup->n_nonlinear, setup->nonlinear,
                           setup->static_force, setup->force, omega, &o, coef, &its, err);
    if (rc) return rc;
    /* the layout's first n (2 H' + 1) entries are the truncation to H' harmonics */
    o.harmonics = RTHS_FIDELITY_NL_HARMONICS / 2;
    memcpy(coef_half, coef, sizeof *coef * (size_t)n * (size_t)(2 * o.harmonics + 1));
    rc = rths_hb_solve(&setup->assembly, setup->n_nonlinear, setup->nonlinear, setup->static_force,
                       setup->force, omega, &o, coef_half, &its, err);
    if (rc) return rc;
    p->true_amplitude_m = hypot(coef[dof + n], coef[dof + 2 * n]);
    p->truth_truncation =
        fabs(hypot(coef_half[dof + n], coef_half[dof + 2 * n]) - p->true_amplitude_m) /
        p->true_amplitude_m;
    return RTHS_OK;
}

int rths_fidelity_nl_compute(const rths_setup *setup, const rths_controller_options *copt,
                             const double *freqs_hz, int count, rths_fidelity_nl_point *out,
                             rths_error *err) {
    const char *why;
    if (!rths_fidelity_nl_applies(setup, &why))
        return rths_error_set(err, RTHS_EINPUT, "the nonlinear fidelity does not apply: %s", why);
    const int n = setup->assembly.n;
    rths_setup sim = *setup;
    rths_split split;
    int rc = all_numerical_split(setup, &split, err);
    if (rc) return rc;
    sim.split = split;
    for (int e = 0; e < sim.n_nonlinear; e++)
        sim.nonlinear[e].numerical = 1;
    sim.interface_mass = RTHS_INTERFACE_MASS_PHYSICAL_SHARE; /* nothing compensated */
    sim.actuator_transform = sim.sensor_transform = NULL;
    rths_controller_options o = *copt;
    o.ramp_time_s = 0;
    o.grounding_kp_n_per_m = o.grounding_kd_n_s_per_m = 0;
    memset(o.grounding_kp_dof, 0, sizeof o.grounding_kp_dof);
    memset(o.grounding_kd_dof, 0, sizeof o.grounding_kd_dof);
    o.gain_matrix_rows = o.gain_matrix_cols = 0;
    o.track_static = 0;
    o.output_dofs = 0;
    o.plant_applies_forcing = 0;
    rths_controller *c = NULL;
    double *coef = calloc((size_t)n * (2 * RTHS_FIDELITY_NL_HARMONICS + 1), sizeof *coef);
    double *coef_half = calloc((size_t)n * (2 * RTHS_FIDELITY_NL_HARMONICS + 1), sizeof *coef);
    if (!coef || !coef_half) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_controller_create(&sim, &o, &c, err);
    for (int i = 0; i < count && !rc; i++) {
        rths_fidelity_nl_point *p = &out[i];
        memset(p, 0, sizeof *p);
        p->frequency_hz = freqs_hz[i];
        /* from the previous frequency's solution, else from rest (the linear solution first);
         * near a fold harmonic balance without continuation may converge to neither: that point
         * gets no truth (nan), and the sweep goes on */
        rths_error ignored;
        if (truth(setup, 2 * M_PI * freqs_hz[i], coef, coef_half, p, &ignored)) {
            memset(coef, 0, sizeof *coef * (size_t)n * (2 * RTHS_FIDELITY_NL_HARMONICS + 1));
            if (truth(setup, 2 * M_PI * freqs_hz[i], coef, coef_half, p, &ignored)) {
                memset(coef, 0, sizeof *coef * (size_t)n * (2 * RTHS_FIDELITY_NL_HARMONICS + 1));
                p->true_amplitude_m = p->truth_truncation = NAN;
            }
        }
        rths_controller_set_forcing(c, freqs_hz[i], setup->forcing_amplitude_n);
        if (i == 0) rths_controller_arm(c, 1);
        if (settle(c, freqs_hz[i], o.sample_rate_hz, p)) {
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
            break;
        }
        if (rths_controller_fault(c) != RTHS_RIG_OK)
            rc = rths_error_set(err, RTHS_EFAIL,
                                "the step's simulation of the assembly latched a fault at %g Hz",
                                freqs_hz[i]);
        p->error_relative = fabs(p->step_amplitude_m - p->true_amplitude_m) / p->true_amplitude_m;
    }
    rths_controller_destroy(c);
    rths_split_free(&split);
    free(coef);
    free(coef_half);
    return rc;
}
