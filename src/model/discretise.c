/* Second-order models in state space and their discretisations (docs/method.md, "Numerical
 * substructure integration"). */
#include "rths/model.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *const scheme_names[RTHS_SCHEME_COUNT] = {"implicit_euler", "trapezoidal",
                                                            "exact_zoh", "exact_foh"};

const char *rths_scheme_name(rths_scheme s) {
    return (s >= 0 && s < RTHS_SCHEME_COUNT) ? scheme_names[s] : "unknown";
}

int rths_scheme_parse(const char *name, rths_scheme *out) {
    for (int s = 0; s < RTHS_SCHEME_COUNT; s++)
        if (name && !strcmp(name, scheme_names[s])) {
            *out = (rths_scheme)s;
            return 0;
        }
    return -1;
}

int rths_state_space(int n, const double *mass, const double *damping, const double *stiffness,
                     int n_inputs, const double *input, double **a_out, double **b_out,
                     rths_error *err) {
    int nx = 2 * n;
    double *a = rths_mat_new(nx, nx), *b = rths_mat_new(nx, n_inputs);
    /* rhs = [K C input] so one factorisation of M gives M^{-1}K, M^{-1}C, M^{-1}input */
    double *rhs = rths_mat_new(n, 2 * n + n_inputs), *m = rths_mat_dup(mass, n, n);
    if (!a || !b || !rhs || !m) {
        free(a), free(b), free(rhs), free(m);
        return rths_error_set(err, RTHS_EFAIL, "out of memory building a state-space model");
    }
    size_t nn = (size_t)n * (size_t)n;
    memcpy(rhs, stiffness, nn * sizeof(double));
    memcpy(rhs + nn, damping, nn * sizeof(double));
    memcpy(rhs + 2 * nn, input, (size_t)n * (size_t)n_inputs * sizeof(double));
    int info = rths_mat_solve(n, 2 * n + n_inputs, m, rhs);
    free(m);
    if (info != 0) {
        free(a), free(b), free(rhs);
        return rths_error_set(err, RTHS_EINPUT, "mass matrix is singular (dgesv info %d)", info);
    }
    for (int i = 0; i < n; i++) {
        RTHS_AT(a, nx, i, n + i) = 1.0;
        for (int j = 0; j < n; j++) {
            RTHS_AT(a, nx, n + i, j) = -RTHS_AT(rhs, n, i, j);
            RTHS_AT(a, nx, n + i, n + j) = -RTHS_AT(rhs, n, i, n + j);
        }
        for (int j = 0; j < n_inputs; j++)
            RTHS_AT(b, nx, n + i, j) = RTHS_AT(rhs, n, i, 2 * n + j);
    }
    free(rhs);
    *a_out = a;
    *b_out = b;
    return RTHS_OK;
}

void rths_discrete_free(rths_discrete *d) {
    if (!d) return;
    rths_mat_free(d->ad);
    rths_mat_free(d->b_prev);
    rths_mat_free(d->b_curr);
    memset(d, 0, sizeof *d);
}

/* (I - c h A)^{-1} applied to [rhs_x | rhs_u] in place. */
static int solve_shifted(int nx, const double *a, double c, double h, int ncols, double *rhs) {
    double *m = rths_mat_new(nx, nx);
    if (!m) return -1;
    for (int j = 0; j < nx; j++)
        for (int i = 0; i < nx; i++)
            RTHS_AT(m, nx, i, j) = (i == j ? 1.0 : 0.0) - c * h * RTHS_AT(a, nx, i, j);
    int info = rths_mat_solve(nx, ncols, m, rhs);
    free(m);
    return info;
}

int rths_discretise(int nx, int nu, const double *a, const double *b, double h, rths_scheme scheme,
                    rths_discrete *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    if (!(isfinite(h) && h > 0))
        return rths_error_set(err, RTHS_EINPUT, "time step must be positive, got %g s", h);
    out->nx = nx;
    out->nu = nu;
    out->h = h;
    out->scheme = scheme;
    out->ad = rths_mat_new(nx, nx);
    out->b_prev = rths_mat_new(nx, nu);
    out->b_curr = rths_mat_new(nx, nu);
    if (!out->ad || !out->b_prev || !out->b_curr) goto oom;
    size_t xx = (size_t)nx * (size_t)nx, xu = (size_t)nx * (size_t)nu;
    int info = 0;
    switch (scheme) {
    case RTHS_SCHEME_IMPLICIT_EULER:
    case RTHS_SCHEME_TRAPEZOIDAL: {
        /* implicit Euler: (I - hA) x' = x + h B u_{k+1};
         * trapezoidal: (I - hA/2) x' = (I + hA/2) x + h/2 B (u_k + u_{k+1}) */
        int trap = scheme == RTHS_SCHEME_TRAPEZOIDAL;
        double c = trap ? 0.5 : 1.0;
        double *rhs = rths_mat_new(nx, nx + nu);
        if (!rhs) goto oom;
        for (int j = 0; j < nx; j++)
            for (int i = 0; i < nx; i++)
                RTHS_AT(rhs, nx, i, j) =
                    (i == j ? 1.0 : 0.0) + (trap ? c * h : 0.0) * RTHS_AT(a, nx, i, j);
        for (size_t k = 0; k < xu; k++)
            rhs[xx + k] = c * h * b[k];
        info = solve_shifted(nx, a, c, h, nx + nu, rhs);
        memcpy(out->ad, rhs, xx * sizeof(double));
        memcpy(out->b_curr, rhs + xx, xu * sizeof(double));
        if (trap) memcpy(out->b_prev, rhs + xx, xu * sizeof(double));
        free(rhs);
        break;
    }
    case RTHS_SCHEME_EXACT_ZOH:
    case RTHS_SCHEME_EXACT_FOH: {
        /* Augmented generator G h = [[A h, B h, 0], [0, 0, I], [0, 0, 0]]: the state (x, w1, w2)
         * with w1' = w2 / h models u = u_k + (t/h)(u_{k+1} - u_k). Blocks of e^{Gh}: (1,1) = Phi,
         * (1,2) = Gamma0 = int_0^h e^{As} ds B, (1,3) = Gamma1 = int_0^h e^{A(h-s)} B s/h ds. */
        int foh = scheme == RTHS_SCHEME_EXACT_FOH;
        int ng = nx + nu * (foh ? 2 : 1);
        double *g = rths_mat_new(ng, ng), *e = rths_mat_new(ng, ng);
        if (!g || !e) {
            free(g), free(e);
            goto oom;
        }
        for (int j = 0; j < nx; j++)
            for (int i = 0; i < nx; i++)
                RTHS_AT(g, ng, i, j) = h * RTHS_AT(a, nx, i, j);
        for (int j = 0; j < nu; j++)
            for (int i = 0; i < nx; i++)
                RTHS_AT(g, ng, i, nx + j) = h * RTHS_AT(b, nx, i, j);
        if (foh)
            for (int j = 0; j < nu; j++)
                RTHS_AT(g, ng, nx + j, nx + nu + j) = 1.0;
        info = rths_expm(ng, g, e);
        for (int j = 0; j < nx; j++)
            for (int i = 0; i < nx; i++)
                RTHS_AT(out->ad, nx, i, j) = RTHS_AT(e, ng, i, j);
        for (int j = 0; j < nu; j++)
            for (int i = 0; i < nx; i++) {
                double gamma0 = RTHS_AT(e, ng, i, nx + j);
                double gamma1 = foh ? RTHS_AT(e, ng, i, nx + nu + j) : 0.0;
                RTHS_AT(out->b_prev, nx, i, j) = gamma0 - gamma1;
                RTHS_AT(out->b_curr, nx, i, j) = gamma1;
            }
        free(g), free(e);
        break;
    }
    default:
        rths_discrete_free(out);
        return rths_error_set(err, RTHS_EINPUT, "unknown integration scheme %d", (int)scheme);
    }
    if (info != 0) {
        rths_discrete_free(out);
        return rths_error_set(err, RTHS_EFAIL, "discretisation (%s) failed: LAPACK info %d",
                              rths_scheme_name(scheme), info);
    }
    return RTHS_OK;
oom:
    rths_discrete_free(out);
    return rths_error_set(err, RTHS_EFAIL, "out of memory discretising a %d-state model", nx);
}

double rths_spectral_radius(int n, const double *a) {
    double *work = rths_mat_dup(a, n, n), *wr = malloc(sizeof(double) * (size_t)(n > 0 ? n : 1)),
           *wi = malloc(sizeof(double) * (size_t)(n > 0 ? n : 1)), dummy = 0, radius = -1;
    if (work && wr && wi &&
        !LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', n, work, n, wr, wi, &dummy, 1, &dummy, 1)) {
        radius = 0;
        for (int i = 0; i < n; i++)
            radius = fmax(radius, hypot(wr[i], wi[i]));
    }
    free(work), free(wr), free(wi);
    return radius;
}

double rths_grounding_loop_radius(int nx, int n_in, const double *ad, const double *b_prev,
                                  const double *b_curr, double h, int ni, const double *gkp,
                                  const double *gkd) {
    const int N = 2 * nx + n_in;
    double *w = rths_mat_new(N, N);
    if (!w) return -1;
    for (int j = 0; j < nx; j++)
        for (int i = 0; i < nx; i++)
            RTHS_AT(w, N, i, j) = ad[i + j * nx];
    for (int j = 0; j < n_in; j++)
        for (int i = 0; i < nx; i++)
            RTHS_AT(w, N, i, 2 * nx + j) = b_prev[i + j * nx];
    for (int i = 0; i < nx; i++)
        RTHS_AT(w, N, nx + i, i) = 1.0;
    for (int d = 0; d < ni; d++) {
        double g1 = -(gkp[d] + gkd[d] / h), g0 = gkd[d] / h;
        for (int i = 0; i < nx; i++) {
            RTHS_AT(w, N, i, d) += b_curr[i + d * nx] * g1;
            RTHS_AT(w, N, i, nx + d) += b_curr[i + d * nx] * g0;
        }
        RTHS_AT(w, N, 2 * nx + d, d) = g1;
        RTHS_AT(w, N, 2 * nx + d, nx + d) = g0;
    }
    double radius = rths_spectral_radius(N, w);
    rths_mat_free(w);
    return radius;
}
