/* Hybrid steady state at a perfect interface match, per integration scheme (docs/method.md,
 * "Numerical substructure integration"); see include/rths/fidelity.h for the model. */
#include "rths/fidelity.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rths_fidelity {
    int n, np, nn, n_int, n_phys, nu;
    int nr;            /* size of the numerical model integrated: nn, or the reduction's */
    double *transform; /* nn x nr: q_num = T r (NULL: no reduction, T = I) */
    double *mass_r, *damping_r, *stiffness_r; /* nr x nr: the numerical model (continuous) */
    double *input_r;                          /* nr x nu: its inputs */
    rths_frf_sweep *truth;                    /* banded FRF of the assembly (NULL: dense) */
    rths_assembly truth_model;                /* views of mass, damping, stiffness for it */
    int *phys_map; /* np: assembly index of physical-side row (phys..., int...) */
    int *num_map;  /* nn: assembly index of numerical-side row (int..., num...) */
    double *mass_phys, *damping_phys, *stiffness_phys; /* np x np */
    double *mass, *damping, *stiffness;                /* n x n, the recombined assembly */
    double *force;                                     /* n */
    double *force_phys;                                /* np: internal physical DoFs only */
    double h;
    rths_discrete disc[RTHS_SCHEME_COUNT];
};

void rths_fidelity_free(rths_fidelity *f) {
    if (!f) return;
    free(f->phys_map);
    free(f->num_map);
    free(f->mass_phys);
    free(f->damping_phys);
    free(f->stiffness_phys);
    free(f->mass);
    free(f->damping);
    free(f->stiffness);
    free(f->force);
    free(f->force_phys);
    free(f->transform);
    free(f->mass_r);
    free(f->damping_r);
    free(f->stiffness_r);
    free(f->input_r);
    rths_frf_sweep_destroy(f->truth);
    for (int s = 0; s < RTHS_SCHEME_COUNT; s++)
        rths_discrete_free(&f->disc[s]);
    free(f);
}

int rths_fidelity_dofs(const rths_fidelity *f) {
    return f->n;
}

/* The numerical model the schemes discretise: the split's, or its reduction; inputs are the
 * interface forces and the forcing (projected by T^T when reduced). */
static int numerical_model(rths_fidelity *f, const rths_split *s, const double *force,
                           const rths_reduced *red) {
    int nn = f->nn, nr = f->nr, nu = f->nu, n_int = f->n_int;
    double *input = rths_mat_new(nn, nu);
    if (!input) return -1;
    for (int j = 0; j < n_int; j++)
        RTHS_AT(input, nn, j, j) = 1.0;
    for (int i = 0; i < nn; i++)
        RTHS_AT(input, nn, i, n_int) = force[f->num_map[i]];
    if (!red) {
        f->input_r = input;
        f->mass_r = rths_mat_dup(s->mass_num, nn, nn);
        f->damping_r = rths_mat_dup(s->damping_num, nn, nn);
        f->stiffness_r = rths_mat_dup(s->stiffness_num, nn, nn);
    } else {
        f->input_r = rths_mat_new(nr, nu);
        if (f->input_r) rths_mat_mul(nr, nu, nn, 1.0, red->transform, 1, input, 0, 0.0, f->input_r);
        free(input);
        f->transform = rths_mat_dup(red->transform, nn, nr);
        f->mass_r = rths_mat_dup(red->mass, nr, nr);
        f->damping_r = rths_mat_dup(red->damping, nr, nr);
        f->stiffness_r = rths_mat_dup(red->stiffness, nr, nr);
    }
    return f->input_r && f->mass_r && f->damping_r && f->stiffness_r && (!red || f->transform) ? 0
                                                                                               : -1;
}

/* The true assembly's FRF by banded solves when it is banded (rths_frf_sweep needs no modes on
 * that path); NULL otherwise: dense solves, as cheap for the seed's few DoFs. */
static int truth_sweep(rths_fidelity *f, rths_error *err) {
    rths_assembly a = {
        .n = f->n, .mass = f->mass, .damping = f->damping, .stiffness = f->stiffness};
    if (!(f->n > 8 && rths_assembly_half_bandwidth(&a) <= f->n / 8)) return RTHS_OK;
    int *all = malloc(sizeof(int) * (size_t)f->n);
    if (!all) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < f->n; i++)
        all[i] = i;
    f->truth_model = a;
    rths_modes none = {0};
    int rc = rths_frf_sweep_create(&f->truth_model, &none, f->force, f->n, all, &f->truth, err);
    free(all);
    return rc;
}

int rths_fidelity_create(const rths_split *s, const double *force, double h_s, rths_fidelity **out,
                         rths_error *err) {
    return rths_fidelity_create_reduced(s, force, h_s, NULL, out, err);
}

int rths_fidelity_create_reduced(const rths_split *s, const double *force, double h_s,
                                 const rths_reduced *red, rths_fidelity **out, rths_error *err) {
    *out = NULL;
    if (!(isfinite(h_s) && h_s > 0))
        return rths_error_set(err, RTHS_EINPUT, "sample step must be positive, got %g s", h_s);
    for (int i = 0; i < s->n; i++)
        if (!isfinite(force[i]))
            return rths_error_set(err, RTHS_EINPUT, "forcing amplitude on DoF %d is not finite",
                                  i + 1);
    if (red && (red->n != s->nn || red->n_boundary != s->n_int))
        return rths_error_set(err, RTHS_EINPUT,
                              "the reduction is of a %d-DoF model with %d interface DoFs; the "
                              "numerical substructure has %d and %d",
                              red->n, red->n_boundary, s->nn, s->n_int);
    rths_fidelity *f = calloc(1, sizeof *f);
    if (!f) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int n = s->n, np = s->np, nn = s->nn, n_int = s->n_int;
    f->n = n, f->np = np, f->nn = nn, f->n_int = n_int, f->n_phys = s->n_phys;
    f->nr = red ? red->nr : nn;
    f->nu = n_int + 1; /* the interface forces, then the (sampled) forcing */
    f->h = h_s;
    f->phys_map = malloc((size_t)np * sizeof *f->phys_map);
    f->num_map = malloc((size_t)nn * sizeof *f->num_map);
    f->mass_phys = rths_mat_dup(s->mass_phys, np, np);
    f->damping_phys = rths_mat_dup(s->damping_phys, np, np);
    f->stiffness_phys = rths_mat_dup(s->stiffness_phys, np, np);
    f->mass = rths_mat_new(n, n);
    f->damping = rths_mat_new(n, n);
    f->stiffness = rths_mat_new(n, n);
    f->force = rths_mat_dup(force, n, 1);
    f->force_phys = rths_mat_new(np, 1);
    double *a = NULL, *b = NULL;
    int rc = RTHS_OK;
    if (!f->phys_map || !f->num_map || !f->mass_phys || !f->damping_phys || !f->stiffness_phys ||
        !f->mass || !f->damping || !f->stiffness || !f->force || !f->force_phys) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    for (int i = 0; i < s->n_phys; i++)
        f->phys_map[i] = s->phys_dofs[i];
    for (int j = 0; j < n_int; j++) {
        f->phys_map[s->n_phys + j] = s->int_dofs[j];
        f->num_map[j] = s->int_dofs[j];
    }
    for (int i = 0; i < s->n_num; i++)
        f->num_map[n_int + i] = s->num_dofs[i];
    rths_split_recombine(s, f->mass, f->damping, f->stiffness);
    /* Only internal physical DoFs are forced in continuous time; the controller applies forcing on
     * the interface and numerical DoFs to the numerical model, at the samples. */
    for (int i = 0; i < s->n_phys; i++)
        f->force_phys[i] = force[s->phys_dofs[i]];
    if (numerical_model(f, s, force, red)) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    rc = truth_sweep(f, err);
    if (!rc)
        rc = rths_state_space(f->nr, f->mass_r, f->damping_r, f->stiffness_r, f->nu, f->input_r, &a,
                              &b, err);
    for (int sc = 0; sc < RTHS_SCHEME_COUNT && !rc; sc++)
        rc = rths_discretise(2 * f->nr, f->nu, a, b, h_s, (rths_scheme)sc, &f->disc[sc], err);
done:
    free(a);
    free(b);
    if (rc) {
        rths_fidelity_free(f);
        return rc;
    }
    *out = f;
    return RTHS_OK;
}

/* G = C (zI - Ad)^{-1} (b_prev + z b_curr): nr x nu displacement response of the discretised
 * numerical model to sampled harmonic inputs. */
static int numerical_transfer(const rths_fidelity *f, const rths_discrete *d, double omega,
                              double complex *g) {
    int nx = d->nx, nu = d->nu;
    double complex z = cexp(I * omega * d->h);
    double complex *m = malloc((size_t)nx * (size_t)nx * sizeof *m);
    double complex *y = malloc((size_t)nx * (size_t)nu * sizeof *y);
    if (!m || !y) {
        free(m), free(y);
        return -1;
    }
    for (int j = 0; j < nx; j++)
        for (int i = 0; i < nx; i++)
            RTHS_AT(m, nx, i, j) = (i == j ? z : 0.0) - RTHS_AT(d->ad, nx, i, j);
    for (int j = 0; j < nu; j++)
        for (int i = 0; i < nx; i++)
            RTHS_AT(y, nx, i, j) = RTHS_AT(d->b_prev, nx, i, j) + z * RTHS_AT(d->b_curr, nx, i, j);
    int info = rths_cmat_solve(nx, nu, m, y);
    if (!info)
        for (int j = 0; j < nu; j++)
            for (int i = 0; i < f->nr; i++)
                RTHS_AT(g, f->nr, i, j) = RTHS_AT(y, nx, i, j);
    free(m), free(y);
    return info;
}

/* G = (K_r - w^2 M_r + i w C_r)^{-1} inputs: the numerical model in continuous time. */
static int continuous_transfer(const rths_fidelity *f, double omega, double complex *g) {
    int nr = f->nr, nu = f->nu;
    double complex *m = malloc((size_t)nr * (size_t)nr * sizeof *m);
    if (!m) return -1;
    for (int k = 0; k < nr * nr; k++)
        m[k] = f->stiffness_r[k] - omega * omega * f->mass_r[k] + I * omega * f->damping_r[k];
    for (int k = 0; k < nr * nu; k++)
        g[k] = f->input_r[k];
    int info = rths_cmat_solve(nr, nu, m, g);
    free(m);
    return info;
}

/* Internal numerical DoFs from the model's coordinates r (nr): q = T r, or r itself. */
static void numerical_dofs(const rths_fidelity *f, const double complex *r, double complex *x_out) {
    for (int i = f->n_int; i < f->nn; i++) {
        double complex q = f->transform ? 0 : r[i];
        for (int c = 0; f->transform && c < f->nr; c++)
            q += RTHS_AT(f->transform, f->nn, i, c) * r[c];
        x_out[f->num_map[i]] = q;
    }
}

/* d == NULL: the numerical model in continuous time (RTHS_FIDELITY_REDUCED). */
static int hybrid_response(const rths_fidelity *f, const rths_discrete *d, double omega,
                           double complex *x_out, rths_error *err) {
    int np = f->np, nn = f->nr, n_int = f->n_int, n_phys = f->n_phys, nu = f->nu;
    int ms = np + n_int;
    const char *name = d ? rths_scheme_name(d->scheme) : "reduced, continuous";
    double complex *g = malloc((size_t)nn * (size_t)nu * sizeof *g);
    double complex *sys = calloc((size_t)ms * (size_t)ms, sizeof *sys);
    double complex *v = calloc((size_t)ms, sizeof *v);
    double complex *r = malloc((size_t)nn * sizeof *r);
    int rc = RTHS_OK;
    if (!g || !sys || !v || !r) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    int info = d ? numerical_transfer(f, d, omega, g) : continuous_transfer(f, omega, g);
    if (info) {
        rc = rths_error_set(err, RTHS_EFAIL,
                            "numerical substructure (%s) has a pole on the unit circle at "
                            "%g rad/s (info %d)",
                            name, omega, info);
        goto done;
    }
    /* unknowns v = (Q_p, lambda); rows: physical equations of motion, interface compatibility */
    for (int j = 0; j < np; j++)
        for (int i = 0; i < np; i++)
            RTHS_AT(sys, ms, i, j) = RTHS_AT(f->stiffness_phys, np, i, j) -
                                     omega * omega * RTHS_AT(f->mass_phys, np, i, j) +
                                     I * omega * RTHS_AT(f->damping_phys, np, i, j);
    for (int k = 0; k < n_int; k++) {
        RTHS_AT(sys, ms, n_phys + k, np + k) = -1.0;
        RTHS_AT(sys, ms, np + k, n_phys + k) = 1.0;
        for (int l = 0; l < n_int; l++)
            RTHS_AT(sys, ms, np + k, np + l) = RTHS_AT(g, nn, k, l);
        v[np + k] = RTHS_AT(g, nn, k, n_int);
    }
    for (int i = 0; i < np; i++)
        v[i] = f->force_phys[i];
    info = rths_cmat_solve(ms, 1, sys, v);
    if (info) {
        rc = rths_error_set(err, RTHS_EFAIL,
                            "hybrid system (%s) is singular at %g rad/s (zgesv info %d)", name,
                            omega, info);
        goto done;
    }
    for (int i = 0; i < np; i++)
        x_out[f->phys_map[i]] = v[i];
    for (int i = 0; i < nn; i++) {
        r[i] = RTHS_AT(g, nn, i, n_int);
        for (int l = 0; l < n_int; l++)
            r[i] -= RTHS_AT(g, nn, i, l) * v[np + l];
    }
    numerical_dofs(f, r, x_out);
done:
    free(g), free(sys), free(v), free(r);
    return rc;
}

int rths_fidelity_response(const rths_fidelity *f, int curve, double omega_rad_s,
                           double complex *x_out, rths_error *err) {
    if (!(isfinite(omega_rad_s) && omega_rad_s > 0))
        return rths_error_set(err, RTHS_EINPUT, "frequency must be positive, got %g rad/s",
                              omega_rad_s);
    if (curve == RTHS_FIDELITY_TRUE && f->truth)
        return rths_frf_sweep_eval(f->truth, omega_rad_s, x_out, err);
    if (curve == RTHS_FIDELITY_TRUE)
        return rths_frf(f->n, f->mass, f->damping, f->stiffness, f->force, omega_rad_s, x_out, err);
    if (curve == RTHS_FIDELITY_REDUCED) return hybrid_response(f, NULL, omega_rad_s, x_out, err);
    if (curve < 0 || curve >= RTHS_SCHEME_COUNT)
        return rths_error_set(err, RTHS_EINPUT, "unknown fidelity curve %d", curve);
    return hybrid_response(f, &f->disc[curve], omega_rad_s, x_out, err);
}

static int amplitude(const rths_fidelity *f, int curve, int dof, double hz, double complex *work,
                     double *amp, rths_error *err) {
    int rc = rths_fidelity_response(f, curve, 2 * M_PI * hz, work, err);
    if (!rc) *amp = cabs(work[dof]);
    return rc;
}

int rths_fidelity_peak(const rths_fidelity *f, int curve, int dof, double lo_hz, double hi_hz,
                       int points, double *peak_hz, double *peak_amplitude_m, rths_error *err) {
    if (dof < 0 || dof >= f->n)
        return rths_error_set(err, RTHS_EINPUT, "DoF %d is outside 1..%d", dof + 1, f->n);
    if (!(lo_hz > 0 && hi_hz > lo_hz && isfinite(hi_hz)) || points < 3)
        return rths_error_set(err, RTHS_EINPUT,
                              "peak search needs 0 < lo < hi and >= 3 points (got %g..%g Hz, %d)",
                              lo_hz, hi_hz, points);
    double complex *work = malloc((size_t)f->n * sizeof *work);
    if (!work) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = RTHS_OK, best = 0;
    double best_amp = -1, step = (hi_hz - lo_hz) / (points - 1);
    for (int i = 0; i < points && !rc; i++) {
        double a;
        rc = amplitude(f, curve, dof, lo_hz + i * step, work, &a, err);
        if (!rc && a > best_amp) best_amp = a, best = i;
    }
    /* golden section inside the scan cell pair around the best point (unimodal there when the
     * scan resolves the peak) */
    double a = lo_hz + (best > 0 ? best - 1 : 0) * step;
    double b = lo_hz + (best < points - 1 ? best + 1 : points - 1) * step;
    const double r = (sqrt(5.0) - 1) / 2;
    double x1 = b - r * (b - a), x2 = a + r * (b - a), f1 = 0, f2 = 0;
    if (!rc) rc = amplitude(f, curve, dof, x1, work, &f1, err);
    if (!rc) rc = amplitude(f, curve, dof, x2, work, &f2, err);
    while (!rc && b - a > 1e-10 * b) {
        if (f1 > f2) {
            b = x2, x2 = x1, f2 = f1;
            x1 = b - r * (b - a);
            rc = amplitude(f, curve, dof, x1, work, &f1, err);
        } else {
            a = x1, x1 = x2, f1 = f2;
            x2 = a + r * (b - a);
            rc = amplitude(f, curve, dof, x2, work, &f2, err);
        }
    }
    if (!rc) {
        double hz = 0.5 * (a + b), amp;
        rc = amplitude(f, curve, dof, hz, work, &amp, err);
        /* the scan point wins if refinement could not beat it (peak on the range's edge) */
        if (!rc && amp < best_amp) hz = lo_hz + best * step, amp = best_amp;
        if (!rc) *peak_hz = hz, *peak_amplitude_m = amp;
    }
    free(work);
    return rc;
}

double rths_fidelity_half_power_hz(const rths_fidelity *f, int curve, int dof, double peak_hz,
                                   double peak_amplitude_m, double end_hz, double step_hz) {
    double complex *x = malloc((size_t)f->n * sizeof *x);
    double half_power_hz = 0;
    rths_error err;
    for (double hz = peak_hz; x && step_hz > 0 && hz < end_hz; hz += step_hz) {
        if (rths_fidelity_response(f, curve, 2 * M_PI * hz, x, &err)) break;
        if (cabs(x[dof]) < peak_amplitude_m / sqrt(2.0)) {
            half_power_hz = hz - peak_hz;
            break;
        }
    }
    free(x);
    return half_power_hz;
}
