/* The corrector alone on classic nonlinear systems with known roots, as GSL's multiroot tests
 * (test_funcs.c) do: Rosenbrock, Powell singular, Helical valley, Freudenstein-Roth and Powell
 * badly scaled (Moré, Garbow & Hillstrom, ACM TOMS 7, 1981, problems 1, 13, 7, 2 and 3, from their
 * standard starting points), and a Duffing oscillator's harmonic balance whose root follows from
 * the amplitude equation. Each runs noise-free and with seeded Gaussian noise on every residual
 * entry (the evaluation reports that noise as its standard error, as a rig measurement does).
 *
 * Tolerances. Noise-free: ||F|| < 1e-10 is asked; at a regular root x - x* = J^-1 F to first
 * order, so |x - x*| <= ||J^-1||_F ||F|| (J^-1 computed here from the analytic Jacobian) with a
 * factor 10 for the second-order term. With noise of standard deviation s per entry the corrector
 * stops once the measured ||F|| < 3 s sqrt(n) (its noise floor); the true ||F|| then is below that
 * plus the noise itself (< 3 s sqrt(n) with probability > 0.99 for n <= 4), so
 * |x - x*| <= ||J^-1||_F 6 s sqrt(n), again with a factor 10 of margin. Singular roots (Powell
 * singular) are bounded through their squared terms instead (see there). */
#include "testlib.h"

#include "rths/config.h"
#include "rths/iterate.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { NMAX = 2 * RTHS_MAX_HARMONICS };

typedef struct analytic analytic;
struct analytic {
    const char *name;
    int n;
    void (*f)(const double *x, double *fx);
    void (*jac)(const double *x, double *J); /* column-major n x n, for the bounds */
    double x0[NMAX], root[NMAX];
    int singular_root;
    double noise; /* standard deviation added to each entry (0: none) */
    rths_rng rng;
};

/* ---- the systems ---- */

static void rosenbrock(const double *x, double *f) {
    f[0] = 10 * (x[1] - x[0] * x[0]);
    f[1] = 1 - x[0];
}
static void rosenbrock_j(const double *x, double *J) {
    J[0] = -20 * x[0], J[1] = -1, J[2] = 10, J[3] = 0;
}

static void powell_singular(const double *x, double *f) {
    f[0] = x[0] + 10 * x[1];
    f[1] = sqrt(5.0) * (x[2] - x[3]);
    f[2] = (x[1] - 2 * x[2]) * (x[1] - 2 * x[2]);
    f[3] = sqrt(10.0) * (x[0] - x[3]) * (x[0] - x[3]);
}

static double helical_theta(const double *x) {
    return atan2(x[1], x[0]) / (2 * M_PI); /* MGH's branch: (0, 1/2] for x2 = 0, x1 < 0 */
}
static void helical(const double *x, double *f) {
    f[0] = 10 * (x[2] - 10 * helical_theta(x));
    f[1] = 10 * (hypot(x[0], x[1]) - 1);
    f[2] = x[2];
}
static void helical_j(const double *x, double *J) {
    double r2 = x[0] * x[0] + x[1] * x[1], r = sqrt(r2);
    /* d theta / dx1 = -x2 / (2 pi r^2), d theta / dx2 = x1 / (2 pi r^2) */
    J[0] = 100 * x[1] / (2 * M_PI * r2), J[1] = 10 * x[0] / r, J[2] = 0;
    J[3] = -100 * x[0] / (2 * M_PI * r2), J[4] = 10 * x[1] / r, J[5] = 0;
    J[6] = 10, J[7] = 0, J[8] = 1;
}

static void roth(const double *x, double *f) {
    f[0] = -13 + x[0] + ((5 - x[1]) * x[1] - 2) * x[1];
    f[1] = -29 + x[0] + ((x[1] + 1) * x[1] - 14) * x[1];
}
static void roth_j(const double *x, double *J) {
    J[0] = 1, J[1] = 1;
    J[2] = 10 * x[1] - 3 * x[1] * x[1] - 2, J[3] = 3 * x[1] * x[1] + 2 * x[1] - 14;
}

static void powell_scaled(const double *x, double *f) {
    f[0] = 1e4 * x[0] * x[1] - 1;
    f[1] = exp(-x[0]) + exp(-x[1]) - 1.0001;
}
static void powell_scaled_j(const double *x, double *J) {
    J[0] = 1e4 * x[1], J[1] = -exp(-x[0]), J[2] = 1e4 * x[0], J[3] = -exp(-x[1]);
}

/* Duffing oscillator m x'' + c x' + k x + k3 x^3 = F cos(w t), one harmonic x = a cos + b sin:
 * F1 = (k - m w^2) a + c w b + 3/4 k3 A^2 a - F, F2 = (k - m w^2) b - c w a + 3/4 k3 A^2 b,
 * A^2 = a^2 + b^2 (residuals in newtons, unknowns in millimetres so both are O(1)). Below the
 * folds the amplitude equation [(k - m w^2 + 3/4 k3 A^2)^2 + (c w)^2] A^2 = F^2 has one root. */
static const double duf_m = 1, duf_c = 2, duf_k = 4000, duf_k3 = 4e9, duf_F = 5, duf_w = 50;
static double duf_keff(double A) {
    return duf_k - duf_m * duf_w * duf_w + 0.75 * duf_k3 * A * A;
}
static void duffing(const double *x, double *f) {
    double a = 1e-3 * x[0], b = 1e-3 * x[1], ke = duf_keff(hypot(a, b));
    f[0] = ke * a + duf_c * duf_w * b - duf_F;
    f[1] = ke * b - duf_c * duf_w * a;
}
static void duffing_j(const double *x, double *J) {
    double a = 1e-3 * x[0], b = 1e-3 * x[1], ke = duf_keff(hypot(a, b)), q = 1.5 * duf_k3;
    J[0] = 1e-3 * (ke + q * a * a), J[1] = 1e-3 * (q * a * b - duf_c * duf_w);
    J[2] = 1e-3 * (q * a * b + duf_c * duf_w), J[3] = 1e-3 * (ke + q * b * b);
}
/* The root from the amplitude equation, by bisection on A (monotone below the folds). */
static void duffing_root(double *root) {
    double lo = 0, hi = 1;
    for (int i = 0; i < 200; i++) {
        double A = 0.5 * (lo + hi), ke = duf_keff(A);
        if ((ke * ke + duf_c * duf_c * duf_w * duf_w) * A * A < duf_F * duf_F)
            lo = A;
        else
            hi = A;
    }
    double A = 0.5 * (lo + hi), ke = duf_keff(A), d = ke * ke + duf_c * duf_c * duf_w * duf_w;
    root[0] = 1e3 * duf_F * ke / d;
    root[1] = 1e3 * duf_F * duf_c * duf_w / d;
}

/* ---- the zero problem over an analytic system ---- */

static int analytic_eval(void *ctx, const double *u, double omega_rad_s, rths_residual *out,
                         rths_error *err) {
    (void)omega_rad_s;
    (void)err;
    analytic *p = ctx;
    memset(out, 0, sizeof *out);
    out->n = p->n;
    p->f(u, out->phi);
    for (int i = 0; i < p->n; i++) {
        out->phi[i] += p->noise * rths_rng_normal(&p->rng);
        out->phi_se[i] = p->noise;
        out->response[i] = out->phi[i]; /* Phi = response - reference, reference 0 */
        out->response_se[i] = p->noise;
    }
    out->samples = 1; /* one sample: nothing to pool */
    return RTHS_OK;
}

static void options_for(const analytic *p, rths_newton_options *opt) {
    rths_newton_defaults(opt, 0);
    opt->max_iterations = 200;
    opt->rel_tolerance = 0;
    opt->abs_tolerance_m = 1e-10;
    opt->noise_factor = 3.0;
    /* forward differences: sqrt(machine epsilon) noise-free; above the noise (error s / h of
     * 1e-4 relative) with it */
    opt->fd_step_rel = p->noise > 0 ? 1e-2 : 1e-7;
    opt->fd_step_min_m = 0;
    opt->step_limit = 0; /* rig safety only: an analytic system has no stroke */
    opt->report_matched = 0;
}

/* Solves p from its starting point; returns the status, the root in x and the evaluations. */
static rths_corrector_outcome solve(analytic *p, double *x, int *evaluations) {
    rths_zero_problem problem = {.n = p->n, .harmonics = 0, .eval = analytic_eval, .ctx = p};
    rths_newton_options opt;
    options_for(p, &opt);
    rths_corrector *c;
    rths_error err;
    assert_int_equal(rths_corrector_create(&problem, &opt, &c, &err), RTHS_OK);
    rths_corrector_set_scales(c, 1.0, 1.0);
    int rc = rths_corrector_solve(c, p->x0, 1.0, NULL, &err);
    if (rc && getenv("RTHS_TEST_VERBOSE")) fprintf(stderr, "%s: %s\n", p->name, err.msg);
    rths_corrector_unknowns(c, x);
    rths_corrector_counters(c, evaluations, NULL, NULL);
    rths_corrector_outcome status = rths_corrector_status(c);
    rths_corrector_destroy(c);
    return status;
}

/* Frobenius norm of J^-1 at the root (an upper bound of its 2-norm). */
static double inverse_norm(const analytic *p) {
    double J[NMAX * NMAX], inv[NMAX * NMAX] = {0}, s = 0;
    p->jac(p->root, J);
    for (int i = 0; i < p->n; i++)
        inv[i + i * p->n] = 1;
    assert_int_equal(rths_mat_solve(p->n, p->n, J, inv), 0);
    for (int i = 0; i < p->n * p->n; i++)
        s += inv[i] * inv[i];
    return sqrt(s);
}

static void check_root(analytic *p) {
    double x[NMAX];
    int evaluations;
    rths_corrector_outcome status = solve(p, x, &evaluations);
    double err = 0;
    for (int i = 0; i < p->n; i++)
        err = fmax(err, fabs(x[i] - p->root[i]));
    double floor = p->noise > 0 ? 6 * p->noise * sqrt(p->n) : 1e-10, bound;
    if (p->singular_root)
        /* Powell singular: |x2 - 2 x3| <= ||F||^1/2 and |x1 - x4| <= (||F|| / sqrt 10)^1/2 from
         * the squared entries; with the two linear entries (<= ||F||) they form a regular linear
         * system in x whose inverse has entries below 1.2 (computed once), so |x| <=
         * 4 * 1.2 * ||F||^1/2; a factor 2 of margin */
        bound = 2 * 4 * 1.2 * sqrt(floor);
    else
        bound = 10 * inverse_norm(p) * floor;
    if (getenv("RTHS_TEST_VERBOSE"))
        fprintf(stderr,
                "%-22s noise %.0e: status %d, %4d evaluations, |x - x*| %.2e (bound %.2e)\n",
                p->name, p->noise, status, evaluations, err, bound);
    /* at a singular root under noise Newton's linear convergence meets the noise floor: a step
     * can then no longer show a reduction, and the corrector says so (stuck) at the floor */
    if (!(p->singular_root && p->noise > 0 && status == RTHS_CORRECTOR_STUCK))
        assert_int_equal(status, RTHS_CORRECTOR_CONVERGED);
    assert_true(err <= bound);
}

static analytic classic(int which, double noise) {
    analytic p = {.noise = noise};
    rths_rng_seed(&p.rng, 11 + (uint64_t)which);
    switch (which) {
    case 0:
        p = (analytic){"Rosenbrock", 2, rosenbrock, rosenbrock_j, {-1.2, 1},
                       {1, 1},       0, noise,      p.rng};
        break;
    case 1:
        p = (analytic){"Powell singular", 4, powell_singular, NULL, {3, -1, 0, 1},
                       {0, 0, 0, 0},      1, noise,           p.rng};
        break;
    case 2:
        p = (analytic){"Helical valley", 3, helical, helical_j, {-1, 0, 0},
                       {1, 0, 0},        0, noise,   p.rng};
        break;
    case 3:
        /* from MGH's start (0.5, -2) Newton with a line search on ||F|| ends in the local
         * minimum of ||F|| at (11.41, -0.8968) (see test_roth_local_minimum); from (4, 3) the
         * root's basin */
        p = (analytic){"Freudenstein-Roth", 2, roth, roth_j, {4, 3}, {5, 4}, 0, noise, p.rng};
        break;
    case 4:
        p = (analytic){"Powell badly scaled",
                       2,
                       powell_scaled,
                       powell_scaled_j,
                       {0, 1},
                       {1.098159329699759e-05, 9.106146739867318},
                       0,
                       noise,
                       p.rng};
        break;
    default:
        p = (analytic){
            "Duffing harmonic balance", 2, duffing, duffing_j, {0, 0}, {0, 0}, 0, noise, p.rng};
        duffing_root(p.root);
        break;
    }
    return p;
}

enum { N_SYSTEMS = 6 };

static void test_noise_free(void **state) {
    (void)state;
    for (int which = 0; which < N_SYSTEMS; which++) {
        analytic p = classic(which, 0.0);
        check_root(&p);
    }
}

/* Noise 1e-6 per entry: six orders below the residuals' starting size. Powell badly scaled is
 * left out: its root's second unknown is determined only to 1e-4 / |exp(-9.1)| = 1 per 1e-4 of
 * residual noise, so no noisy measurement can place it (its J^-1 norm is 9e3). */
static void test_with_noise(void **state) {
    (void)state;
    for (int which = 0; which < N_SYSTEMS; which++) {
        if (which == 4) continue;
        analytic p = classic(which, 1e-6);
        check_root(&p);
    }
}

/* Freudenstein-Roth from MGH's start: the local minimum of ||F|| at (11.41, -0.8968), where
 * ||F|| = 6.999, is no root, and a line search on ||F|| cannot leave it. The corrector must say
 * so, not report convergence. */
static void test_roth_local_minimum(void **state) {
    (void)state;
    analytic p = classic(3, 0.0);
    p.x0[0] = 0.5;
    p.x0[1] = -2;
    double x[NMAX];
    int evaluations;
    rths_corrector_outcome status = solve(&p, x, &evaluations);
    assert_true(status == RTHS_CORRECTOR_STUCK || status == RTHS_CORRECTOR_MAX_ITER);
    double f[2];
    roth(x, f);
    assert_true(hypot(f[0], f[1]) > 6.9);
}

/* The life cycle step by step: status CONTINUE until converged, then CONVERGED; save() after it
 * and load() into a new corrector carries the Jacobian, so a nearby start needs no
 * finite-difference Jacobian (fewer evaluations); a record of another size or format is refused
 * with a message naming both. */
static void test_life_cycle(void **state) {
    (void)state;
    analytic p = classic(5, 0.0);
    rths_zero_problem problem = {.n = 2, .eval = analytic_eval, .ctx = &p};
    rths_newton_options opt;
    options_for(&p, &opt);
    rths_corrector *c;
    rths_error err;
    assert_int_equal(rths_corrector_create(&problem, &opt, &c, &err), RTHS_OK);
    rths_corrector_set_scales(c, 1.0, 1.0);
    assert_int_equal(rths_corrector_set(c, p.x0, 1.0, NULL, &err), RTHS_OK);
    int steps = 0;
    while (rths_corrector_status(c) == RTHS_CORRECTOR_CONTINUE && steps < 100) {
        assert_int_equal(rths_corrector_iterate(c, &err), RTHS_OK);
        steps++;
    }
    assert_int_equal(rths_corrector_status(c), RTHS_CORRECTOR_CONVERGED);
    int first, iterations;
    rths_corrector_counters(c, &first, &iterations, NULL);
    assert_int_equal(iterations, steps);
    const rths_solution *sol = rths_corrector_solution(c);
    assert_true(sol->converged);
    assert_true(sol->residual_norm_m < 1e-10);
    static rths_corrector_saved saved;
    rths_corrector_save(c, &saved);
    rths_corrector_destroy(c);

    assert_int_equal(rths_corrector_create(&problem, &opt, &c, &err), RTHS_OK);
    rths_corrector_set_scales(c, 1.0, 1.0);
    assert_int_equal(rths_corrector_load(c, &saved, &err), RTHS_OK);
    double near[2] = {p.root[0] * 1.01, p.root[1] * 0.99};
    assert_int_equal(rths_corrector_solve(c, near, 1.0, NULL, &err), RTHS_OK);
    int again;
    rths_corrector_counters(c, &again, NULL, NULL);
    assert_true(again < first);
    assert_true(again <= 8); /* no 2-evaluation FD Jacobian, a few Broyden steps */
    rths_corrector_destroy(c);

    rths_zero_problem bigger = {.n = 3, .eval = analytic_eval, .ctx = &p};
    assert_int_equal(rths_corrector_create(&bigger, &opt, &c, &err), RTHS_OK);
    assert_int_equal(rths_corrector_load(c, &saved, &err), RTHS_EINPUT);
    saved.format = 99;
    assert_int_equal(rths_corrector_load(c, &saved, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "format 99"));
    assert_non_null(strstr(err.msg, "format 1"));
    rths_corrector_destroy(c);
}

/* ---- a failed full step repairs the carried Jacobian (rths_newton_options.secant_repair) ----
 * A linear rig Phi(u) = A (u - u*) whose slope along u_0 reverses between two corrections (as
 * past a fold): the second starts from the first's Jacobian, A's old value, so its full Newton
 * step doubles the residual, and every shorter step along it is worse too (|Phi| = 1 + lambda
 * for a start one unit off). The failed trial is an exact secant of a linear rig: Broyden's
 * update along the step gives J = A (the error lies along the step), and the next step lands on
 * the root: 3 evaluations. Halving instead tries lambda = 1 .. 1/16 (5), then measures a fresh
 * Jacobian (2) and steps (1): 9. */
typedef struct reversing_rig {
    double slope0; /* A = diag(slope0, 1) */
    double root[2];
} reversing_rig;

static int reversing_eval(void *ctx, const double *u, double omega_rad_s, rths_residual *out,
                          rths_error *err) {
    (void)omega_rad_s;
    (void)err;
    const reversing_rig *r = ctx;
    memset(out, 0, sizeof *out);
    out->n = 2;
    out->phi[0] = r->slope0 * (u[0] - r->root[0]);
    out->phi[1] = u[1] - r->root[1];
    memcpy(out->response, out->phi, sizeof out->phi);
    out->samples = 1;
    return RTHS_OK;
}

/* What rths_newton_options.on_evaluation reported: each evaluation's role as a letter
 * (P prediction, J Jacobian column, S step, D damped step), its damping, mismatch and tolerance. */
typedef struct evaluation_log {
    char roles[64];
    int n;
    double damping[64], mismatch[64], ratio[64];
    int within[64];
} evaluation_log;

static void log_evaluation(void *user, const rths_evaluation_event *e) {
    evaluation_log *log = user;
    static const char letter[] = "PJSDGA";
    if (log->n >= 63) return;
    log->roles[log->n] = letter[e->role];
    log->damping[log->n] = e->damping;
    log->mismatch[log->n] = e->mismatch_m;
    log->ratio[log->n] = e->mismatch_to_tolerance;
    log->within[log->n] = e->within_tolerance;
    log->roles[++log->n] = '\0';
}

/* Evaluations of the second correction, started `offset` along u_0 from the root, with a
 * tolerance of 0.1 (so the start lies offset / 0.1 tolerances off); the root must be reached.
 * With log, what the hook reported of the second correction. */
static int evaluations_logged_after_reversal(int repair, double offset, evaluation_log *log) {
    reversing_rig rig = {.slope0 = 1.0, .root = {0.3, -0.2}};
    rths_zero_problem problem = {.n = 2, .eval = reversing_eval, .ctx = &rig};
    rths_newton_options opt;
    rths_newton_defaults(&opt, 0);
    assert_int_equal(opt.secant_repair, 0); /* off by default */
    opt.secant_repair = repair;
    opt.rel_tolerance = 0;
    opt.abs_tolerance_m = 0.1;
    opt.fd_step_rel = 1e-3; /* a linear rig: any step is exact */
    opt.fd_step_min_m = 0;
    opt.step_limit = 0;
    opt.report_matched = 0;
    evaluation_log unused;
    opt.on_evaluation = log_evaluation;
    opt.on_evaluation_user = log ? log : &unused;
    memset(opt.on_evaluation_user, 0, sizeof(evaluation_log));
    rths_corrector *c;
    rths_error err;
    assert_int_equal(rths_corrector_create(&problem, &opt, &c, &err), RTHS_OK);
    rths_corrector_set_scales(c, 1.0, 1.0);
    double start[2] = {rig.root[0] + 0.5, rig.root[1] + 0.5};
    assert_int_equal(rths_corrector_solve(c, start, 1.0, NULL, &err), RTHS_OK);
    assert_int_equal(rths_corrector_status(c), RTHS_CORRECTOR_CONVERGED);
    memset(opt.on_evaluation_user, 0, sizeof(evaluation_log)); /* the second correction's */
    rig.slope0 = -1.0;
    start[0] = rig.root[0] + offset;
    start[1] = rig.root[1];
    assert_int_equal(rths_corrector_solve(c, start, 1.0, NULL, &err), RTHS_OK);
    assert_int_equal(rths_corrector_status(c), RTHS_CORRECTOR_CONVERGED);
    double u[2];
    rths_corrector_unknowns(c, u);
    assert_true(fabs(u[0] - rig.root[0]) < 1e-9 && fabs(u[1] - rig.root[1]) < 1e-9);
    int evaluations;
    rths_corrector_counters(c, &evaluations, NULL, NULL);
    rths_corrector_destroy(c);
    return evaluations;
}

static int evaluations_after_reversal(int repair, double offset) {
    return evaluations_logged_after_reversal(repair, offset, NULL);
}

/* rths_newton_options.on_evaluation reports every evaluation with its role, in order: the
 * reversing rig's two corrections of test_failed_step_repairs_the_jacobian, whose sequences and
 * mismatches are known in closed form (|Phi| = 1 + lambda along the step after the reversal, for
 * a start one unit off; the tolerance 0.1). */
static void test_evaluation_hook(void **state) {
    (void)state;
    evaluation_log log;
    /* halved: the full step and four shorter ones, a 2-column Jacobian, the step to the root */
    assert_int_equal(evaluations_logged_after_reversal(0, 1.0, &log), 9);
    assert_int_equal(log.n, 9);
    assert_string_equal(log.roles, "PSDDDDJJS");
    assert_true(fabs(log.mismatch[0] - 1.0) < 1e-12);
    assert_true(fabs(log.ratio[0] - 10.0) < 1e-9);
    assert_false(log.within[0]);
    static const double lambda[5] = {1.0, 0.5, 0.25, 0.125, 0.0625};
    for (int k = 0; k < 5; k++) {
        assert_true(fabs(log.damping[1 + k] - lambda[k]) < 1e-15);
        assert_true(fabs(log.mismatch[1 + k] - (1.0 + lambda[k])) < 1e-9);
    }
    assert_true(log.damping[0] == 0.0 && log.damping[6] == 0.0); /* not steps */
    assert_true(log.within[8] && log.mismatch[8] < 1e-9);
    /* repaired: the failed full step, then the step from the repaired Jacobian */
    assert_int_equal(evaluations_logged_after_reversal(1, 1.0, &log), 3);
    assert_string_equal(log.roles, "PSS");
    assert_true(fabs(log.mismatch[1] - 2.0) < 1e-9);
    assert_true(log.within[2]);
    assert_string_equal(rths_evaluation_role_name(RTHS_EVALUATION_DAMPED_STEP), "damped_step");
    assert_string_equal(rths_evaluation_role_name(RTHS_EVALUATION_ACCURACY_STEP), "accuracy_step");
}

static void test_failed_step_repairs_the_jacobian(void **state) {
    (void)state;
    /* 10 tolerances off: repaired */
    assert_int_equal(evaluations_after_reversal(1, 1.0), 3);
    assert_int_equal(evaluations_after_reversal(0, 1.0), 9);
    /* 100 tolerances off (beyond the 50 of SECANT_REPAIR_MAX_TOLERANCES) a long step's secant
     * is no local slope: halved, then measured, as without the repair */
    assert_int_equal(evaluations_after_reversal(1, 10.0), 9);
    assert_int_equal(evaluations_after_reversal(0, 10.0), 9);
}

/* iteration.secant_repair: off with either strategy unless the key sets it. */
static void test_secant_repair_config(void **state) {
    (void)state;
    static const char *const sets[] = {NULL, "iteration.secant_repair=false",
                                       "iteration.secant_repair=true"};
    for (int paper = 0; paper < 2; paper++)
        for (int k = 0; k < 3; k++) {
            rths_config *cfg = NULL;
            rths_error err;
            if (rths_config_load(NULL, &sets[k], sets[k] ? 1 : 0, &cfg, &err))
                fail_msg("%s", err.msg);
            rths_settle_options st;
            rths_newton_options nw;
            rths_settle_defaults(&st, paper);
            rths_newton_defaults(&nw, paper);
            int harmonics = 1;
            if (rths_iterate_config_read(cfg, &st, &nw, &harmonics, &err)) fail_msg("%s", err.msg);
            assert_int_equal(nw.secant_repair, k == 2);
            rths_config_free(cfg);
        }
}

/* A problem size the corrector cannot hold is refused at create. */
static void test_refuses_bad_size(void **state) {
    (void)state;
    analytic p = classic(0, 0.0);
    rths_newton_options opt;
    options_for(&p, &opt);
    rths_corrector *c = NULL;
    rths_error err;
    rths_zero_problem too_big = {.n = NMAX + 1, .eval = analytic_eval, .ctx = &p};
    assert_int_equal(rths_corrector_create(&too_big, &opt, &c, &err), RTHS_EINPUT);
    assert_null(c);
    rths_zero_problem odd_fourier = {.n = 3, .harmonics = 1, .eval = analytic_eval, .ctx = &p};
    assert_int_equal(rths_corrector_create(&odd_fourier, &opt, &c, &err), RTHS_EINPUT);
}

/* ---- a linear map over two interface DoFs: the n x n residual model ----
 *
 * Phi = G(w) z - f(w) and response x = R(w) z + e(w) with z the two DoFs' complex targets
 * (z_d = A*_d + i B*_d, iterate.h's pair layout for N = 1), every gain and offset exactly linear
 * in w, G and R full 2 x 2 (each DoF's target drives both DoFs). The local model the corrector
 * fits is then exact: its prediction is z = G(w)^-1 f(w) and its Jacobian blocks are G's, to
 * rounding. With `conjugate` the map also holds a term in conj(z), which no complex gain
 * represents: the rig is not LTI-like and no prediction is offered. */
typedef struct {
    int conjugate;
} two_dof_map;

static const double map_w0 = 80.0;
static double complex map_g(int d, int e, double w) {
    static const double complex g0[2][2] = {{0.8 + 0.3 * I, -0.25 + 0.1 * I},
                                            {0.15 - 0.2 * I, 0.6 - 0.4 * I}};
    static const double complex g1[2][2] = {{0.01 - 0.02 * I, 0.005 * I},
                                            {-0.004, 0.02 + 0.01 * I}};
    return g0[d][e] + g1[d][e] * (w - map_w0);
}
static double complex map_f(int d, double w) {
    return (d ? 2e-4 - 1e-4 * I : -1e-4 + 3e-4 * I) * (1 + 0.01 * (w - map_w0));
}
static double complex map_r(int d, int e, double w) {
    return (d == e ? 1.1 : 0.2) + 0.003 * I * (w - map_w0) * (d + 1);
}

static int two_dof_eval(void *ctx, const double *u, double w, rths_residual *out, rths_error *err) {
    (void)err;
    const two_dof_map *m = ctx;
    double complex z[2] = {u[0] + I * u[2], u[1] + I * u[3]};
    memset(out, 0, sizeof *out);
    out->n = 4;
    for (int d = 0; d < 2; d++) {
        double complex phi = -map_f(d, w), x = 1e-5;
        for (int e = 0; e < 2; e++) {
            phi += map_g(d, e, w) * z[e] + (m->conjugate ? 0.3 * conj(z[e]) : 0);
            x += map_r(d, e, w) * z[e];
        }
        out->phi[d] = creal(phi), out->phi[2 + d] = cimag(phi);
        out->response[d] = creal(x), out->response[2 + d] = cimag(x);
        out->reference[d] = creal(x - phi), out->reference[2 + d] = cimag(x - phi);
    }
    out->rig_time_s = 1;
    return RTHS_OK;
}

/* Three corrections at 79, 80 and 81 rad/s fill the history; the prediction at 82 rad/s is
 * G^-1 f to 1e-8 relative and the seeded Jacobian's blocks are G's and R's to 1e-8 (the model is
 * exact, so only rounding in the normal equations remains: measured 2e-11; a wrong block layout
 * or a DoF's gain put in another's place is off by order one). */
static void test_two_dof_lti_model(void **state) {
    (void)state;
    for (int conjugate = 0; conjugate <= 1; conjugate++) {
        two_dof_map map = {.conjugate = conjugate};
        rths_zero_problem problem = {
            .n = 4, .harmonics = 2, .interface_dofs = 2, .eval = two_dof_eval, .ctx = &map};
        rths_newton_options opt;
        rths_newton_defaults(&opt, 0);
        opt.abs_tolerance_m = 1e-14;
        opt.rel_tolerance = 1e-12;
        rths_corrector *c;
        rths_error err;
        assert_int_equal(rths_corrector_create(&problem, &opt, &c, &err), RTHS_OK);
        double u[4] = {0};
        for (double w = 79; w <= 81; w += 1) {
            assert_int_equal(rths_corrector_solve(c, u, w, NULL, &err), RTHS_OK);
            rths_corrector_unknowns(c, u);
        }
        double w = 82, pred[4];
        int rc = rths_corrector_lti_predict(c, w, pred);
        if (conjugate) {
            assert_int_equal(rc, -1);
            rths_corrector_destroy(c);
            continue;
        }
        assert_int_equal(rc, 0);
        double complex a[2][2] = {{map_g(0, 0, w), map_g(0, 1, w)},
                                  {map_g(1, 0, w), map_g(1, 1, w)}};
        double complex det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        double complex z[2] = {(a[1][1] * map_f(0, w) - a[0][1] * map_f(1, w)) / det,
                               (a[0][0] * map_f(1, w) - a[1][0] * map_f(0, w)) / det};
        double size = hypot(cabs(z[0]), cabs(z[1]));
        print_message("prediction off by %.2e, %.2e relative\n",
                      cabs(pred[0] + I * pred[2] - z[0]) / size,
                      cabs(pred[1] + I * pred[3] - z[1]) / size);
        for (int d = 0; d < 2; d++) {
            assert_true(fabs(pred[d] - creal(z[d])) < 1e-8 * size);
            assert_true(fabs(pred[2 + d] - cimag(z[d])) < 1e-8 * size);
        }
        static rths_corrector_saved saved;
        double J[RTHS_MAX_UNKNOWNS * RTHS_MAX_UNKNOWNS], R[RTHS_MAX_UNKNOWNS * RTHS_MAX_UNKNOWNS];
        rths_corrector_save(c, &saved);
        assert_int_equal(rths_corrector_saved_jacobians(&saved, J, R), 1);
        for (int d = 0; d < 2; d++)
            for (int e = 0; e < 2; e++) { /* block (d, e): [[Re g, -Im g], [Im g, Re g]] */
                double complex g = map_g(d, e, w);
                assert_true(fabs(J[d + e * RTHS_MAX_UNKNOWNS] - creal(g)) < 1e-8);
                assert_true(fabs(J[2 + d + e * RTHS_MAX_UNKNOWNS] - cimag(g)) < 1e-8);
                assert_true(fabs(J[d + (2 + e) * RTHS_MAX_UNKNOWNS] + cimag(g)) < 1e-8);
                assert_true(fabs(R[d + e * RTHS_MAX_UNKNOWNS] - creal(map_r(d, e, w))) < 1e-8);
            }
        rths_corrector_destroy(c);
    }
}

/* One DoF, straight in everything: Phi = g z - f, x = r z + e (metres). */
static const double complex line_g = 0.8 + 0.3 * I, line_f = -1e-4 + 3e-4 * I,
                            line_r = 1.1 + 0.2 * I, line_e = 1e-5;
static int line_eval(void *ctx, const double *u, double w, rths_residual *out, rths_error *err) {
    (void)ctx, (void)w, (void)err;
    double complex z = u[0] + I * u[1], phi = line_g * z - line_f, x = line_r * z + line_e;
    memset(out, 0, sizeof *out);
    out->n = 2;
    out->phi[0] = creal(phi), out->phi[1] = cimag(phi);
    out->response[0] = creal(x), out->response[1] = cimag(x);
    out->reference[0] = creal(x - phi), out->reference[1] = cimag(x - phi);
    out->rig_time_s = 1;
    return RTHS_OK;
}

/* A point accepted at its first evaluation with no Jacobian at all (as after a failed correction
 * drops the carried one) measures the gain it needs with one more evaluation, so the reported
 * amplitude is the response at zero mismatch and its standard error covers the step there
 * (se_honest 1). The start is 1e-4 of the root off, within the tolerance: the measurement alone
 * is off by 1e-4 relative; on this straight map the secant gain is exact, so the matched
 * amplitude is |r f / g + e| to rounding (1e-9 relative asked). */
static void test_gain_without_jacobian(void **state) {
    (void)state;
    rths_zero_problem problem = {.n = 2, .harmonics = 1, .interface_dofs = 1, .eval = line_eval};
    rths_newton_options opt;
    rths_newton_defaults(&opt, 0);
    opt.abs_tolerance_m = 1e-7;
    opt.rel_tolerance = 0;
    rths_corrector *c;
    rths_error err;
    assert_int_equal(rths_corrector_create(&problem, &opt, &c, &err), RTHS_OK);
    double complex root = line_f / line_g, start = root * (1 + 1e-4);
    double u[2] = {creal(start), cimag(start)};
    assert_int_equal(rths_corrector_solve(c, u, 80, NULL, &err), RTHS_OK);
    const rths_solution *s = rths_corrector_solution(c);
    int evaluations;
    rths_corrector_counters(c, &evaluations, NULL, NULL);
    double truth = cabs(line_r * root + line_e), measured = cabs(line_r * start + line_e);
    print_message("%d evaluations; measured %.2e off, reported %.2e off, honest %d\n", evaluations,
                  fabs(measured / truth - 1), fabs(s->amplitude_m / truth - 1),
                  s->amplitude_se_honest);
    assert_int_equal(evaluations, 2); /* the point, and the gain's probe */
    assert_int_equal(s->amplitude_se_honest, 1);
    assert_true(fabs(s->amplitude_m / truth - 1) < 1e-9);
    assert_true(s->amplitude_se_m > 0 && s->amplitude_se_m < 1e-3 * truth);
    rths_corrector_destroy(c);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_noise_free),
        cmocka_unit_test(test_with_noise),
        cmocka_unit_test(test_roth_local_minimum),
        cmocka_unit_test(test_life_cycle),
        cmocka_unit_test(test_refuses_bad_size),
        cmocka_unit_test(test_failed_step_repairs_the_jacobian),
        cmocka_unit_test(test_evaluation_hook),
        cmocka_unit_test(test_secant_repair_config),
        cmocka_unit_test(test_two_dof_lti_model),
        cmocka_unit_test(test_gain_without_jacobian),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
