/* The true assembly's interface response and the error of a hybrid point against it. */
#include "rths/truth.h"
#include "rths/signals.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static int truth_alloc(rths_truth_curve *t, int n, rths_error *err);

/* ---- sparse models (setup->sparse): direct sparse solves of the assembly ---- */

int rths_sparse_truth_create(const rths_sparse_model *m, int n_out, const int *out_dofs,
                             rths_sparse_truth **out, rths_error *err) {
    *out = NULL;
    rths_sparse_truth *t = calloc(1, sizeof *t);
    if (!t) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    t->n_out = n_out;
    t->out_dofs = malloc(sizeof(int) * (size_t)(n_out > 0 ? n_out : 1));
    t->last_x = malloc(sizeof *t->last_x * (size_t)(n_out > 0 ? n_out : 1));
    t->last_omega_rad_s = NAN;
    int rc = t->out_dofs && t->last_x ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) memcpy(t->out_dofs, out_dofs, sizeof(int) * (size_t)n_out);
    /* no modes: only rths_sparse_frf_direct is used (the symbolic analysis on its first call) */
    if (!rc) rc = rths_sparse_frf_create(m, NULL, n_out, out_dofs, &t->frf, err);
    if (rc) {
        rths_sparse_truth_free(t);
        return rc;
    }
    *out = t;
    return RTHS_OK;
}

void rths_sparse_truth_free(rths_sparse_truth *t) {
    if (!t) return;
    rths_sparse_frf_destroy(t->frf);
    free(t->out_dofs);
    free(t->last_x);
    free(t);
}

/* The assembly's response at the reported DoFs for one frequency, one sparse complex solve (the
 * last frequency's kept: frf.csv, the summary and the figures ask the same point in turn). */
static int sparse_response(rths_sparse_truth *t, double omega_rad_s, rths_error *err) {
    if (t->last_omega_rad_s == omega_rad_s) return RTHS_OK;
    t->last_omega_rad_s = NAN;
    int rc = rths_sparse_frf_direct(t->frf, omega_rad_s, t->last_x, err);
    if (!rc) t->last_omega_rad_s = omega_rad_s;
    return rc;
}

/* X at the given DoFs from the cache; -1 when one is not a reported DoF or the solve failed. */
static int sparse_response_at(const rths_setup *s, double f_hz, int count, const int *dofs,
                              double complex *x_at) {
    rths_sparse_truth *t = s->sparse_truth;
    rths_error err;
    if (!t || sparse_response(t, 2 * M_PI * f_hz, &err)) return -1;
    for (int i = 0; i < count; i++) {
        int found = -1;
        for (int o = 0; o < t->n_out && found < 0; o++)
            if (t->out_dofs[o] == dofs[i]) found = o;
        if (found < 0) return -1;
        x_at[i] = t->last_x[found];
    }
    return 0;
}

/* The analytic curve of a sparse model: one direct sparse solve per frequency (the modes are
 * `rths model`'s, not computed here) on a uniform grid of model.frf.points (default
 * RTHS_SPARSE_TRUTH_POINTS) over the range. */
#define RTHS_SPARSE_TRUTH_POINTS 201
static int sparse_truth_curve(const rths_setup *s, double lo_hz, double hi_hz, rths_truth_curve *t,
                              rths_error *err) {
    int count = s->frf_points >= 2 ? s->frf_points : RTHS_SPARSE_TRUTH_POINTS;
    int rc = truth_alloc(t, count, err);
    int iface = s->split.int_dofs[0];
    for (int j = 0; j < count && !rc; j++) {
        double f = lo_hz + (hi_hz - lo_hz) * j / (count - 1);
        double complex x;
        t->freq_hz[j] = f;
        t->stable[j] = 1;
        if (f <= 0) f = 1e-6 * (hi_hz > 0 ? hi_hz : 1); /* 0 Hz: the static response */
        rc = sparse_response(s->sparse_truth, 2 * M_PI * f, err);
        if (rc) break;
        if (sparse_response_at(s, f, 1, &iface, &x))
            rc = rths_error_set(err, RTHS_EFAIL, "the sparse truth lost its interface DoF");
        else
            t->amp_m[j] = cabs(x);
    }
    return rc;
}

void rths_truth_free(rths_truth_curve *t) {
    free(t->freq_hz);
    free(t->amp_m);
    free(t->amp_h2_m);
    free(t->amp_h3_m);
    free(t->stable);
    free(t->max_floquet);
    free(t->amp_dof_m);
    memset(t, 0, sizeof *t);
}

static int truth_alloc(rths_truth_curve *t, int n, rths_error *err) {
    t->n = n;
    t->freq_hz = calloc((size_t)n, sizeof(double));
    t->amp_m = calloc((size_t)n, sizeof(double));
    t->amp_h2_m = calloc((size_t)n, sizeof(double));
    t->amp_h3_m = calloc((size_t)n, sizeof(double));
    t->stable = calloc((size_t)n, sizeof(int));
    if (t->freq_hz && t->amp_m && t->amp_h2_m && t->amp_h3_m && t->stable) return RTHS_OK;
    rths_truth_free(t);
    return rths_error_set(err, RTHS_EFAIL, "out of memory");
}

/* Nonlinear elements (either side): shooting with pseudo-arclength through the folds, every
 * harmonic kept. */
static int shooting_truth(const rths_setup *s, double lo_hz, double hi_hz, rths_truth_curve *t,
                          rths_error *err) {
    int iface = s->split.int_dofs[0], n = s->assembly.n;
    rths_shooting_options opt = {.start_hz = lo_hz,
                                 .end_hz = hi_hz,
                                 .steps_per_period = 1024,
                                 .max_step = 0.02,
                                 .max_points = 4000};
    rths_periodic_point *pp = NULL;
    int count = 0;
    int rc = rths_nonlinear_frf(&s->assembly, s->n_nonlinear, s->nonlinear, s->static_force,
                                s->force, &opt, &pp, &count, err);
    if (!rc) rc = truth_alloc(t, count, err);
    if (!rc && !(t->max_floquet = calloc((size_t)count, sizeof(double)))) {
        rths_truth_free(t);
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    /* several interface DoFs: every one's fundamental, as the linear curve gives them (truth.csv's
     * dof<d>_amplitude_m, the figure's curve per DoF) */
    const int dofs = s->split.n_int;
    if (!rc && dofs > 1) {
        t->amp_dof_m = calloc((size_t)count * dofs, sizeof(double));
        if (!t->amp_dof_m) {
            rths_truth_free(t);
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        } else
            t->dofs = dofs;
    }
    for (int j = 0; j < count && !rc; j++) {
        t->freq_hz[j] = pp[j].omega_rad_s / (2 * M_PI);
        t->amp_m[j] = hypot(pp[j].cos_m[iface + n], pp[j].sin_m[iface + n]);
        t->amp_h2_m[j] = hypot(pp[j].cos_m[iface + 2 * n], pp[j].sin_m[iface + 2 * n]);
        t->amp_h3_m[j] = hypot(pp[j].cos_m[iface + 3 * n], pp[j].sin_m[iface + 3 * n]);
        t->stable[j] = pp[j].stable;
        t->max_floquet[j] = pp[j].max_floquet;
        for (int d = 0; d < t->dofs; d++) {
            int dof = s->split.int_dofs[d];
            t->amp_dof_m[d * count + j] = hypot(pp[j].cos_m[dof + n], pp[j].sin_m[dof + n]);
        }
    }
    rths_periodic_points_free(pp, count);
    return rc;
}

/* Several interface DoFs: every one's analytic amplitude on the curve's grid (dense solves: a
 * banded model large enough to need the sweep has few interface DoFs next to its size). */
static int interface_dofs_truth(const rths_setup *s, rths_truth_curve *t, rths_error *err) {
    int n = s->assembly.n, dofs = s->split.n_int, rc = RTHS_OK;
    double complex *x = calloc((size_t)n, sizeof *x);
    t->amp_dof_m = calloc((size_t)(t->n * dofs), sizeof(double));
    if (!x || !t->amp_dof_m) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int j = 0; j < t->n && !rc; j++) {
        rc = rths_frf(n, s->assembly.mass, s->assembly.damping, s->assembly.stiffness, s->force,
                      2 * M_PI * t->freq_hz[j], x, err);
        for (int d = 0; d < dofs && !rc; d++)
            t->amp_dof_m[d * t->n + j] = cabs(x[s->split.int_dofs[d]]);
    }
    if (!rc) t->dofs = dofs;
    free(x);
    return rc;
}

/* Linear structure: the analytic FRF on the modal analysis's frequency grid. */
static int analytic_truth(const rths_setup *s, double lo_hz, double hi_hz, rths_truth_curve *t,
                          rths_error *err) {
    int iface = s->split.int_dofs[0], n = s->assembly.n;
    rths_modes modes;
    double *f = NULL;
    int count = 0;
    int rc = rths_modal_analysis(&s->assembly, &modes, err);
    if (rc) return rc;
    rc = rths_frf_grid(&modes, lo_hz, hi_hz, 0, &f, &count, err);
    /* a banded assembly (a meshed rod or beam) by banded LU, O(n b^2) per frequency instead of a
     * dense n^3 solve (1000 DoFs: 45 s -> well under a second); small ones as before */
    rths_frf_sweep *sweep = NULL;
    if (!rc && n > 8 && rths_assembly_half_bandwidth(&s->assembly) <= n / 8)
        rc = rths_frf_sweep_create(&s->assembly, &modes, s->force, 1, &iface, &sweep, err);
    rths_modes_free(&modes);
    double complex *x = calloc((size_t)n, sizeof *x);
    if (!rc && !x) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = truth_alloc(t, count, err);
    for (int j = 0; j < count && !rc; j++) {
        if (sweep)
            rc = rths_frf_sweep_eval(sweep, 2 * M_PI * f[j], &x[iface], err);
        else
            rc = rths_frf(n, s->assembly.mass, s->assembly.damping, s->assembly.stiffness, s->force,
                          2 * M_PI * f[j], x, err);
        t->freq_hz[j] = f[j];
        t->amp_m[j] = cabs(x[iface]);
        t->stable[j] = 1;
    }
    if (!rc && s->split.n_int > 1) rc = interface_dofs_truth(s, t, err);
    rths_frf_sweep_destroy(sweep);
    free(x);
    free(f);
    return rc;
}

int rths_truth_compute(const rths_setup *s, double lo_hz, double hi_hz, rths_truth_curve *t,
                       rths_error *err) {
    memset(t, 0, sizeof *t);
    int rc = s->sparse         ? sparse_truth_curve(s, lo_hz, hi_hz, t, err)
             : s->has_bilinear ? shooting_truth(s, lo_hz, hi_hz, t, err)
                               : analytic_truth(s, lo_hz, hi_hz, t, err);
    t->exact = !s->has_bilinear;
    return rc;
}

double rths_truth_curve_distance(const rths_truth_curve *t, double f_hz, double amp_m) {
    double best = INFINITY;
    if (!(f_hz > 0 && amp_m > 0)) return best;
    double pu = 10 * log(f_hz), pv = log(amp_m);
    for (int j = 0; j + 1 < t->n; j++) {
        if (!(t->amp_m[j] > 0 && t->amp_m[j + 1] > 0)) continue;
        double u0 = 10 * log(t->freq_hz[j]), v0 = log(t->amp_m[j]);
        double du = 10 * log(t->freq_hz[j + 1]) - u0, dv = log(t->amp_m[j + 1]) - v0;
        double len2 = du * du + dv * dv;
        double x = len2 > 0 ? ((pu - u0) * du + (pv - v0) * dv) / len2 : 0;
        x = x < 0 ? 0 : x > 1 ? 1 : x;
        best = fmin(best, hypot(pu - u0 - x * du, pv - v0 - x * dv));
    }
    return best;
}

/* X at the given DoFs for one frequency: a banded assembly (a meshed rod or beam) by one banded LU,
 * O(n b^2), as the curve's sweep; others by a dense solve. frf.csv, the summary and the figures ask
 * this at every point and truth.csv at every grid frequency: dense, a 1000-DoF chain spent minutes
 * here. Models under 64 DoFs keep the dense solve (the demo's outputs unchanged to the last
 * digit; there it costs microseconds). */
static int linear_response_at(const rths_setup *s, double f_hz, int count, const int *dofs,
                              double complex *x_at) {
    if (s->sparse) return sparse_response_at(s, f_hz, count, dofs, x_at);
    int n = s->assembly.n;
    rths_error err;
    if (n >= 64 && rths_assembly_half_bandwidth(&s->assembly) <= n / 8) {
        rths_modes none = {0}; /* the banded path needs no modes (rths_frf_sweep_create) */
        rths_frf_sweep *sweep = NULL;
        int rc = rths_frf_sweep_create(&s->assembly, &none, s->force, count, dofs, &sweep, &err);
        if (!rc) rc = rths_frf_sweep_eval(sweep, 2 * M_PI * f_hz, x_at, &err);
        rths_frf_sweep_destroy(sweep);
        return rc ? -1 : 0;
    }
    double complex *x = calloc((size_t)n, sizeof *x);
    int rc = -1;
    if (x && !rths_frf(n, s->assembly.mass, s->assembly.damping, s->assembly.stiffness, s->force,
                       2 * M_PI * f_hz, x, &err)) {
        for (int i = 0; i < count; i++)
            x_at[i] = x[dofs[i]];
        rc = 0;
    }
    free(x);
    return rc;
}

int rths_truth_linear_dofs_response(const rths_setup *s, double f_hz, int count, const int *dofs,
                                    double *amp_m, double *phase_rad) {
    for (int i = 0; i < count; i++) {
        amp_m[i] = NAN;
        if (phase_rad) phase_rad[i] = NAN;
    }
    int n = s->assembly.n;
    for (int i = 0; i < count; i++)
        if (dofs[i] < 0 || dofs[i] >= n) return -1;
    if (s->has_bilinear) return -1;
    double complex *x = calloc((size_t)count, sizeof *x);
    /* x(t) = Re(X e^{i w t}) = |X| cos(w t + arg X) for the force Re(F e^{i w t}) */
    int rc = x ? linear_response_at(s, f_hz, count, dofs, x) : -1;
    for (int i = 0; i < count && !rc; i++) {
        amp_m[i] = cabs(x[i]);
        if (phase_rad) phase_rad[i] = carg(x[i]);
    }
    free(x);
    return rc;
}

int rths_truth_linear_dof_amplitudes_m(const rths_setup *s, double f_hz, double *amp_m) {
    return rths_truth_linear_dofs_response(s, f_hz, s->split.n_int, s->split.int_dofs, amp_m, NULL);
}

double rths_truth_linear_amplitude_m(const rths_setup *s, double f_hz) {
    double amp[RTHS_MAX_INTERFACE_DOFS];
    if (s->split.n_int > RTHS_MAX_INTERFACE_DOFS) return NAN;
    rths_truth_linear_dof_amplitudes_m(s, f_hz, amp);
    return amp[0];
}

double rths_truth_relative_error(const rths_setup *s, const rths_truth_curve *t, double f_hz,
                                 double amp_m) {
    if (s->has_bilinear) return rths_truth_curve_distance(t, f_hz, amp_m);
    double truth = rths_truth_linear_amplitude_m(s, f_hz);
    return fabs(amp_m - truth) / truth;
}

/* Whether the curve's frequencies run strictly one way over points j..k (one monotone piece). */
static int monotone(const rths_truth_curve *t, int j, int k) {
    double dir = t->freq_hz[j + 1] - t->freq_hz[j];
    for (int i = j; i < k; i++)
        if (!((t->freq_hz[i + 1] - t->freq_hz[i]) * dir > 0)) return 0;
    return 1;
}

/* The amplitude at f_hz between points j and j + 1: the cubic through j - 1 .. j + 2 when those
 * lie on one monotone piece (the shooting points are up to 0.02 Hz apart, where a straight line
 * is off by several standard errors of a hybrid point near the peak), else the straight line. */
static double interpolate(const rths_truth_curve *t, int j, double f_hz) {
    double f0 = t->freq_hz[j], f1 = t->freq_hz[j + 1];
    double a = t->amp_m[j] + (f_hz - f0) / (f1 - f0) * (t->amp_m[j + 1] - t->amp_m[j]);
    if (j < 1 || j + 2 >= t->n || !monotone(t, j - 1, j + 2)) return a;
    double cubic = 0;
    for (int k = j - 1; k <= j + 2; k++) { /* Lagrange form */
        double w = t->amp_m[k];
        for (int l = j - 1; l <= j + 2; l++)
            if (l != k) w *= (f_hz - t->freq_hz[l]) / (t->freq_hz[k] - t->freq_hz[l]);
        cubic += w;
    }
    return cubic > 0 ? cubic : a;
}

/* The piece [j, j + 1] of the curve on a measured point's branch at f_hz: of the pieces that
 * span f_hz (each a branch there), the one nearest amp_m in log amplitude (the branches of a
 * folded response differ by far more than any error), and its amplitude at f_hz; -1 for none. */
static int branch_piece(const rths_truth_curve *t, double f_hz, double amp_m, double *amp_out) {
    int best = -1;
    double best_gap = INFINITY;
    *amp_out = NAN;
    for (int j = 0; j + 1 < t->n; j++) {
        double f0 = t->freq_hz[j], f1 = t->freq_hz[j + 1];
        if (!((f0 - f_hz) * (f1 - f_hz) <= 0) || f0 == f1) continue;
        double a = interpolate(t, j, f_hz);
        double gap = fabs(log(a / amp_m));
        if (a > 0 && gap < best_gap) {
            best_gap = gap;
            best = j;
            *amp_out = a;
        }
    }
    return best;
}

/* where f_hz lies on piece j, 0 .. 1 */
static double piece_fraction(const rths_truth_curve *t, int j, double f_hz) {
    return (f_hz - t->freq_hz[j]) / (t->freq_hz[j + 1] - t->freq_hz[j]);
}

double rths_truth_branch_amplitude_m(const rths_setup *s, const rths_truth_curve *t, double f_hz,
                                     double amp_m, int *stable) {
    if (stable) *stable = 1;
    if (!s->has_bilinear) return rths_truth_linear_amplitude_m(s, f_hz);
    double a;
    int j = branch_piece(t, f_hz, amp_m, &a);
    if (j >= 0 && stable)
        *stable = piece_fraction(t, j, f_hz) < 0.5 ? t->stable[j] : t->stable[j + 1];
    return a;
}

double rths_truth_branch_max_floquet(const rths_truth_curve *t, double f_hz, double amp_m) {
    if (!t->max_floquet) return NAN;
    double a;
    int j = branch_piece(t, f_hz, amp_m, &a);
    if (j < 0) return NAN;
    double x = piece_fraction(t, j, f_hz);
    return t->max_floquet[j] + x * (t->max_floquet[j + 1] - t->max_floquet[j]);
}

double rths_truth_fold_distance_hz(const rths_truth_curve *t, double f_hz) {
    double best = INFINITY;
    for (int j = 0; j + 1 < t->n; j++)
        if (t->stable[j] != t->stable[j + 1])
            best = fmin(best, fabs(0.5 * (t->freq_hz[j] + t->freq_hz[j + 1]) - f_hz));
    return best;
}
