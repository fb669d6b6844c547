/* Periodic response of the true assembly with nonlinear elements (nonlinear.h): shooting on the
 * full model with pseudo-arclength continuation in frequency. This is the independent truth the
 * hybrid test of a nonlinear structure is judged against: it never touches the hybrid loop, only
 * (M, C, K) and the elements. */
#include "rths/nonlinear.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int n, nx;
    const rths_assembly *a;
    int count;                 /* elements */
    const rths_nl_element *el; /* count of them */
    double *minv_k;            /* M^{-1} K */
    double *minv_c;            /* M^{-1} C */
    double *minv_fs;           /* M^{-1} static force */
    double *minv_f;            /* M^{-1} harmonic force amplitude */
    double *minv_b;            /* n x count: M^{-1} (e_i - e_j) per element */
    int steps;
    double *stages; /* 6 nx: integrate()'s state, RK4 stages and scratch */
} shooter;

const char *rths_nl_type_name(rths_nl_type t) {
    static const char *const names[RTHS_NL_TYPE_COUNT] = {"bilinear", "cubic", "gap", "friction"};
    return t >= 0 && t < RTHS_NL_TYPE_COUNT ? names[t] : "?";
}

int rths_nl_on_rate(const rths_nl_element *e) {
    return e->type == RTHS_NL_FRICTION;
}

double rths_nl_force(const rths_nl_element *e, double y, double *slope) {
    double g = 0, dg = 0;
    switch (e->type) {
    case RTHS_NL_BILINEAR:
    case RTHS_NL_GAP:
        if (y + e->clearance_m < 0) {
            g = e->k * (y + e->clearance_m);
            dg = e->k;
        }
        break;
    case RTHS_NL_CUBIC:
        g = e->k * y * y * y;
        dg = 3 * e->k * y * y;
        break;
    case RTHS_NL_FRICTION: {
        double t = tanh(y / e->v_reg_m_s);
        g = e->force_n * t;
        dg = e->force_n * (1 - t * t) / e->v_reg_m_s;
        break;
    }
    default:
        break;
    }
    if (slope) *slope = dg;
    return g;
}

rths_nl_element rths_nl_from_leg(const rths_bilinear_leg *leg) {
    return (rths_nl_element){.type = RTHS_NL_BILINEAR,
                             .dof_i = leg->upper_dof,
                             .dof_j = leg->lower_dof,
                             .k = (leg->ratio - 1) * leg->stiffness_n_per_m,
                             .leg_stiffness_n_per_m = leg->stiffness_n_per_m,
                             .ratio = leg->ratio};
}

/* The element's coordinate in state x = (q, v): the deformation, or its rate for friction. */
static double element_coordinate(const rths_nl_element *e, int n, const double *x) {
    int off = rths_nl_on_rate(e) ? n : 0;
    return x[off + e->dof_i] - (e->dof_j >= 0 ? x[off + e->dof_j] : 0.0);
}

/* x' = f(t, x): x = (q, v). */
static void rhs(const shooter *s, double wt, const double *x, double *dx) {
    int n = s->n;
    const double *q = x, *v = x + n;
    double g[RTHS_MAX_NONLINEAR];
    for (int e = 0; e < s->count; e++)
        g[e] = rths_nl_force(&s->el[e], element_coordinate(&s->el[e], n, x), NULL);
    double c = cos(wt);
    for (int i = 0; i < n; i++) {
        double acc = s->minv_fs[i] + s->minv_f[i] * c;
        for (int e = 0; e < s->count; e++)
            acc -= g[e] * s->minv_b[i + (size_t)e * n];
        for (int j = 0; j < n; j++)
            acc -= RTHS_AT(s->minv_k, n, i, j) * q[j] + RTHS_AT(s->minv_c, n, i, j) * v[j];
        dx[i] = v[i];
        dx[n + i] = acc;
    }
}

/* dPhi = J(x) Phi, J = [[0, I], [-M^{-1}(K + K_g), -M^{-1}(C + C_g)]]. */
static void rhs_var(const shooter *s, const double *x, const double *phi, double *dphi) {
    int n = s->n, nx = s->nx;
    double slope[RTHS_MAX_NONLINEAR];
    for (int e = 0; e < s->count; e++)
        rths_nl_force(&s->el[e], element_coordinate(&s->el[e], n, x), &slope[e]);
    for (int col = 0; col < nx; col++) {
        const double *p = phi + (size_t)col * nx;
        double *dp = dphi + (size_t)col * nx;
        double dg[RTHS_MAX_NONLINEAR];
        for (int e = 0; e < s->count; e++)
            dg[e] = slope[e] * element_coordinate(&s->el[e], n, p);
        for (int i = 0; i < n; i++) {
            double acc = 0;
            for (int e = 0; e < s->count; e++)
                acc -= dg[e] * s->minv_b[i + (size_t)e * n];
            for (int j = 0; j < n; j++)
                acc -= RTHS_AT(s->minv_k, n, i, j) * p[j] + RTHS_AT(s->minv_c, n, i, j) * p[n + j];
            dp[i] = p[n + i];
            dp[n + i] = acc;
        }
    }
}

/* One forcing period from x0 with RK4; optionally the monodromy matrix and Fourier coefficients
 * of q (rectangle rule over the period: exact for trigonometric polynomials up to steps/2). */
static void integrate(const shooter *s, const double *x0, double omega, double *xT, double *phi,
                      double *cos_m, double *sin_m) {
    int n = s->n, nx = s->nx, N = s->steps;
    double T = 2 * M_PI / omega, h = T / N;
    double *x = s->stages, *k1 = x + nx, *k2 = k1 + nx, *k3 = k2 + nx, *k4 = k3 + nx,
           *tmp = k4 + nx;
    double *P = NULL, *pk = NULL;
    size_t pp = (size_t)nx * nx;
    memcpy(x, x0, (size_t)nx * sizeof(double));
    if (phi) {
        P = phi;
        rths_mat_identity(P, nx);
        pk = malloc(5 * pp * sizeof(double));
    }
    int H = RTHS_PERIODIC_HARMONICS;
    if (cos_m) {
        memset(cos_m, 0, (size_t)n * (H + 1) * sizeof(double));
        memset(sin_m, 0, (size_t)n * (H + 1) * sizeof(double));
    }
    for (int step = 0; step < N; step++) {
        double wt = omega * h * step;
        if (cos_m)
            for (int k = 0; k <= H; k++) {
                double ck = cos(k * wt), sk = sin(k * wt), w = (k == 0 ? 1.0 : 2.0) / N;
                for (int i = 0; i < n; i++) {
                    cos_m[i + k * n] += w * ck * x[i];
                    sin_m[i + k * n] += w * sk * x[i];
                }
            }
        double *K1 = pk, *K2 = pk ? pk + pp : NULL, *K3 = pk ? pk + 2 * pp : NULL,
               *K4 = pk ? pk + 3 * pp : NULL, *PT = pk ? pk + 4 * pp : NULL;
        /* stage 1 */
        rhs(s, wt, x, k1);
        if (P) rhs_var(s, x, P, K1);
        for (int i = 0; i < nx; i++)
            tmp[i] = x[i] + 0.5 * h * k1[i];
        if (P)
            for (size_t i = 0; i < pp; i++)
                PT[i] = P[i] + 0.5 * h * K1[i];
        /* stage 2 */
        rhs(s, wt + 0.5 * omega * h, tmp, k2);
        if (P) rhs_var(s, tmp, PT, K2);
        for (int i = 0; i < nx; i++)
            tmp[i] = x[i] + 0.5 * h * k2[i];
        if (P)
            for (size_t i = 0; i < pp; i++)
                PT[i] = P[i] + 0.5 * h * K2[i];
        /* stage 3 */
        rhs(s, wt + 0.5 * omega * h, tmp, k3);
        if (P) rhs_var(s, tmp, PT, K3);
        for (int i = 0; i < nx; i++)
            tmp[i] = x[i] + h * k3[i];
        if (P)
            for (size_t i = 0; i < pp; i++)
                PT[i] = P[i] + h * K3[i];
        /* stage 4 */
        rhs(s, wt + omega * h, tmp, k4);
        if (P) rhs_var(s, tmp, PT, K4);
        for (int i = 0; i < nx; i++)
            x[i] += h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
        if (P)
            for (size_t i = 0; i < pp; i++)
                P[i] += h / 6 * (K1[i] + 2 * K2[i] + 2 * K3[i] + K4[i]);
    }
    memcpy(xT, x, (size_t)nx * sizeof(double));
    free(pk);
}

/* The tangent stiffness K + sum_e g_e'(d) b_e b_e^T of the deformation-driven elements at q. */
static void tangent_stiffness(const rths_assembly *a, int count, const rths_nl_element *el,
                              const double *q, double *kt, double *g_out) {
    int n = a->n;
    memcpy(kt, a->stiffness, (size_t)n * n * sizeof(double));
    memset(g_out, 0, (size_t)n * sizeof(double));
    for (int e = 0; e < count; e++) {
        if (rths_nl_on_rate(&el[e])) continue;
        int i = el[e].dof_i, j = el[e].dof_j;
        double slope, g = rths_nl_force(&el[e], q[i] - (j >= 0 ? q[j] : 0.0), &slope);
        g_out[i] += g;
        RTHS_AT(kt, n, i, i) += slope;
        if (j >= 0) {
            g_out[j] -= g;
            RTHS_AT(kt, n, j, j) += slope;
            RTHS_AT(kt, n, i, j) -= slope;
            RTHS_AT(kt, n, j, i) -= slope;
        }
    }
}

int rths_nonlinear_static(const rths_assembly *a, int count, const rths_nl_element *el,
                          const double *static_force, double *q_out, rths_error *err) {
    int n = a->n;
    double *kt = rths_mat_new(n, n), *r = malloc((size_t)n * sizeof *r),
           *g = malloc((size_t)n * sizeof *g);
    int rc = kt && r && g ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    /* Newton from the linear solution; a piecewise-linear restoring force converges in a few
     * steps once the active sides are found, a cubic one quadratically near the root. Steps are
     * halved while they do not reduce the residual (a stiffening spring overshoots from afar). */
    memset(q_out, 0, (size_t)n * sizeof(double));
    double scale = 0;
    for (int i = 0; i < n; i++)
        scale = fmax(scale, fabs(static_force[i]));
    int converged = scale == 0;
    for (int it = 0; it < 200 && !rc && !converged; it++) {
        tangent_stiffness(a, count, el, q_out, kt, g);
        double norm = 0;
        for (int i = 0; i < n; i++) {
            double ku = 0;
            for (int j = 0; j < n; j++)
                ku += RTHS_AT(a->stiffness, n, i, j) * q_out[j];
            r[i] = static_force[i] - ku - g[i];
            norm = fmax(norm, fabs(r[i]));
        }
        if (norm <= 1e-12 * scale) {
            converged = 1;
            break;
        }
        if (rths_mat_solve(n, 1, kt, r) != 0) break;
        for (int i = 0; i < n; i++)
            q_out[i] += r[i];
    }
    /* Piecewise-linear elements only: once Newton has found the active pieces, the equilibrium
     * is one linear solve with their stiffness (and their clearances' constant forces); it is
     * taken as the answer, so the seed's leg gets exactly the solve of its stiff side. */
    int piecewise = 1;
    for (int e = 0; e < count; e++)
        piecewise &= el[e].type == RTHS_NL_BILINEAR || el[e].type == RTHS_NL_GAP ||
                     el[e].type == RTHS_NL_FRICTION;
    if (!rc && converged && piecewise && scale > 0) {
        tangent_stiffness(a, count, el, q_out, kt, g);
        memcpy(r, static_force, (size_t)n * sizeof(double));
        for (int e = 0; e < count; e++) {
            if (rths_nl_on_rate(&el[e])) continue;
            int i = el[e].dof_i, j = el[e].dof_j;
            double slope;
            rths_nl_force(&el[e], q_out[i] - (j >= 0 ? q_out[j] : 0.0), &slope);
            double offset = slope * el[e].clearance_m;
            if (offset == 0) continue;
            r[i] -= offset;
            if (j >= 0) r[j] += offset;
        }
        if (rths_mat_solve(n, 1, kt, r) == 0) memcpy(q_out, r, (size_t)n * sizeof(double));
    }
    free(kt), free(r), free(g);
    if (!rc && !converged)
        rc = rths_error_set(err, RTHS_EFAIL,
                            "no static equilibrium found for the nonlinear elements");
    return rc;
}

int rths_bilinear_static(const rths_assembly *a, const rths_bilinear_leg *leg,
                         const double *static_force, double *q_out, rths_error *err) {
    rths_nl_element e = rths_nl_from_leg(leg);
    return rths_nonlinear_static(a, 1, &e, static_force, q_out, err);
}

void rths_periodic_points_free(rths_periodic_point *pts, int n) {
    if (!pts) return;
    for (int i = 0; i < n; i++) {
        free(pts[i].cos_m);
        free(pts[i].sin_m);
    }
    free(pts);
}

typedef struct {
    shooter *s;
    double *sx; /* nx: scale of each state entry */
    /* workspace, allocated once for the whole curve (sizes in unknowns m = nx + 1) */
    double *res_x;        /* 4 nx: shoot_residual's states */
    double *g, *jac, *lu; /* m, m x m, m x m: shoot_newton */
    lapack_int *ipiv;     /* m */
    double *floquet;      /* nx x nx + 2 nx: store_point's monodromy copy, eigenvalues */
    double sw;            /* scale of omega */
    int m;                /* unknowns: nx + 1 */
} shoot_problem;

/* Residual in scaled unknowns y = (x0 / sx, omega / sw): G = (x(T) - x0) / sx, plus the arclength
 * row when tangent != NULL. Jacobian (m x m) when jac != NULL. */
static void shoot_residual(const shoot_problem *p, const double *y, const double *tangent,
                           const double *ypred, double *g, double *jac, double *phi_out) {
    shooter *s = p->s;
    int nx = s->nx, m = p->m;
    double *x0 = p->res_x, *xT = x0 + nx, *x1 = xT + nx, *xp = x1 + nx;
    for (int i = 0; i < nx; i++)
        x0[i] = y[i] * p->sx[i];
    double w = y[nx] * p->sw;
    double *phi = jac ? malloc((size_t)nx * nx * sizeof(double)) : NULL;
    integrate(s, x0, w, xT, phi, NULL, NULL);
    for (int i = 0; i < nx; i++)
        g[i] = (xT[i] - x0[i]) / p->sx[i];
    if (tangent) {
        double r = 0;
        for (int j = 0; j < m; j++)
            r += tangent[j] * (y[j] - ypred[j]);
        g[nx] = r;
    }
    if (jac) {
        for (int j = 0; j < nx; j++)
            for (int i = 0; i < nx; i++)
                jac[i + j * m] = (RTHS_AT(phi, nx, i, j) - (i == j)) * p->sx[j] / p->sx[i];
        /* d/d omega by a central difference: the period itself depends on omega */
        double hw = 1e-6 * w;
        integrate(s, x0, w + hw, xp, NULL, NULL, NULL);
        integrate(s, x0, w - hw, x1, NULL, NULL, NULL);
        for (int i = 0; i < nx; i++)
            jac[i + nx * m] = (xp[i] - x1[i]) / (2 * hw) * p->sw / p->sx[i];
        if (tangent)
            for (int j = 0; j < m; j++)
                jac[nx + j * m] = tangent[j];
        if (phi_out) memcpy(phi_out, phi, (size_t)nx * nx * sizeof(double));
    }
    free(phi);
}

/* Newton on the shooting residual; fixed omega when tangent == NULL. Returns iterations or -1. */
static int shoot_newton(const shoot_problem *p, double *y, const double *tangent,
                        const double *ypred, double *phi_out) {
    int nx = p->s->nx, m = p->m, neq = tangent ? m : nx;
    double *g = p->g, *jac = p->jac, *a = p->lu;
    lapack_int *ipiv = p->ipiv;
    for (int it = 0; it < 15; it++) {
        shoot_residual(p, y, tangent, ypred, g, jac, phi_out);
        double norm = 0;
        for (int i = 0; i < neq; i++)
            norm += g[i] * g[i];
        if (sqrt(norm) < 1e-10) return it;
        for (int j = 0; j < neq; j++)
            for (int i = 0; i < neq; i++)
                a[i + j * neq] = jac[i + j * m];
        for (int i = 0; i < neq; i++)
            g[i] = -g[i];
        if (LAPACKE_dgesv(LAPACK_COL_MAJOR, neq, 1, a, neq, ipiv, g, neq) != 0) return -1;
        double step = 0;
        for (int i = 0; i < neq; i++) {
            y[i] += g[i];
            step += g[i] * g[i];
        }
        if (!isfinite(step)) return -1;
    }
    return -1;
}

static int store_point(shoot_problem *p, const double *y, const double *phi,
                       rths_periodic_point *pt) {
    shooter *s = p->s;
    int n = s->n, nx = s->nx, H = RTHS_PERIODIC_HARMONICS;
    double *x0 = p->res_x, *xT = x0 + nx;
    for (int i = 0; i < nx; i++)
        x0[i] = y[i] * p->sx[i];
    pt->omega_rad_s = y[nx] * p->sw;
    pt->cos_m = calloc((size_t)n * (H + 1), sizeof(double));
    pt->sin_m = calloc((size_t)n * (H + 1), sizeof(double));
    if (!pt->cos_m || !pt->sin_m) return -1;
    integrate(s, x0, pt->omega_rad_s, xT, NULL, pt->cos_m, pt->sin_m);
    double *a = p->floquet, *wr = a + (size_t)nx * nx, *wi = wr + nx, vl[1], vr[1];
    memcpy(a, phi, (size_t)nx * nx * sizeof(double));
    if (LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', nx, a, nx, wr, wi, vl, 1, vr, 1) != 0) return -1;
    double mx = 0;
    for (int i = 0; i < nx; i++)
        mx = fmax(mx, hypot(wr[i], wi[i]));
    pt->max_floquet = mx;
    pt->stable = mx < 1.0 + 1e-6;
    return 0;
}

static void problem_free(shoot_problem *p) {
    free(p->s->stages);
    free(p->sx), free(p->res_x), free(p->g), free(p->ipiv), free(p->floquet);
}

/* Workspace for an nx-state shooting problem, sized once (no DoF limit). */
static int problem_alloc(shoot_problem *p) {
    size_t nx = (size_t)p->s->nx, m = nx + 1;
    p->s->stages = malloc(6 * nx * sizeof(double));
    p->sx = malloc(nx * sizeof(double));
    p->res_x = malloc(4 * nx * sizeof(double));
    p->g = malloc((m + 2 * m * m) * sizeof(double));
    p->ipiv = malloc(m * sizeof *p->ipiv);
    p->floquet = malloc((nx * nx + 2 * nx) * sizeof(double));
    if (p->g) {
        p->jac = p->g + m;
        p->lu = p->jac + m * m;
    }
    return p->s->stages && p->sx && p->res_x && p->g && p->ipiv && p->floquet ? 0 : -1;
}

/* First guess x0 (nx) at start_hz: the linearisation about the static point (the elements'
 * tangent stiffness there, friction's tangent damping at rest); returns the response's size (for
 * the unknowns' scales) or -1 with err set. */
static double first_guess(const shooter *s, const double *static_force, const double *force,
                          double w0, double *x0, rths_error *err) {
    const rths_assembly *a = s->a;
    int n = s->n;
    double *qs = malloc((size_t)n * sizeof *qs), *klin = rths_mat_new(n, n),
           *clin = rths_mat_dup(a->damping, n, n), *g = malloc((size_t)n * sizeof *g);
    double complex *x = malloc((size_t)n * sizeof *x);
    double amp = -1;
    if (!qs || !klin || !clin || !g || !x)
        rths_error_set(err, RTHS_EFAIL, "out of memory");
    else if (!rths_nonlinear_static(a, s->count, s->el, static_force, qs, err)) {
        tangent_stiffness(a, s->count, s->el, qs, klin, g);
        for (int e = 0; e < s->count; e++) {
            if (!rths_nl_on_rate(&s->el[e])) continue;
            double slope;
            rths_nl_force(&s->el[e], 0.0, &slope);
            int i = s->el[e].dof_i, j = s->el[e].dof_j;
            RTHS_AT(clin, n, i, i) += slope;
            if (j >= 0) {
                RTHS_AT(clin, n, j, j) += slope;
                RTHS_AT(clin, n, i, j) -= slope;
                RTHS_AT(clin, n, j, i) -= slope;
            }
        }
        if (!rths_frf(n, a->mass, clin, klin, force, w0, x, err)) {
            amp = 0;
            for (int i = 0; i < n; i++) {
                x0[i] = qs[i] + creal(x[i]);
                x0[n + i] = -w0 * cimag(x[i]);
                amp = fmax(amp, fmax(cabs(x[i]), fabs(qs[i])));
            }
        }
    }
    free(qs), free(klin), free(clin), free(g), free(x);
    return amp;
}

/* Pseudo-arclength continuation from the converged y (m unknowns) to end_hz; points stored in
 * pts (cap of them), their count returned in *np. */
static int trace(shoot_problem *p, const rths_shooting_options *opt, double *y, double *phi,
                 rths_periodic_point *pts, int cap, int *np, rths_error *err) {
    int nx = p->s->nx, m = p->m, rc = RTHS_OK;
    size_t bytes = (size_t)m * sizeof(double);
    double *ys = calloc((size_t)cap * (size_t)m, sizeof(double));
    double *ynew = malloc(3 * bytes), *tangent = ynew ? ynew + m : NULL,
           *pred = ynew ? ynew + 2 * m : NULL;
    if (!ys || !ynew) {
        free(ys), free(ynew);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    double dir = opt->end_hz >= opt->start_hz ? 1 : -1;
    double ds = fmin(opt->max_step, 0.01);
    *np = 0;
    while (*np < cap) {
        if (store_point(p, y, phi, &pts[*np]) != 0) break;
        memcpy(ys + (size_t)*np * m, y, bytes);
        (*np)++;
        if (dir * (y[nx] * p->sw / (2 * M_PI) - opt->end_hz) >= 0) break;
        int it = -1;
        while (ds > 1e-7) {
            if (*np == 1) { /* natural first step */
                memcpy(ynew, y, bytes);
                ynew[nx] += dir * ds;
                it = shoot_newton(p, ynew, NULL, NULL, phi);
            } else {
                const double *y0 = ys + (size_t)(*np - 2) * m;
                double len = 0;
                for (int i = 0; i <= nx; i++) {
                    tangent[i] = y[i] - y0[i];
                    len += tangent[i] * tangent[i];
                }
                len = sqrt(len);
                for (int i = 0; i <= nx; i++) {
                    tangent[i] /= len;
                    pred[i] = y[i] + ds * tangent[i];
                    ynew[i] = pred[i];
                }
                it = shoot_newton(p, ynew, tangent, pred, phi);
            }
            if (it >= 0) break;
            ds *= 0.5;
        }
        if (it < 0) {
            rc = rths_error_set(err, RTHS_EFAIL, "shooting continuation stalled near %g Hz",
                                y[nx] * p->sw / (2 * M_PI));
            break;
        }
        memcpy(y, ynew, bytes);
        if (it <= 3) ds = fmin(ds * 1.3, opt->max_step);
    }
    free(ys), free(ynew);
    return rc;
}

int rths_nonlinear_frf(const rths_assembly *a, int count, const rths_nl_element *el,
                       const double *static_force, const double *force,
                       const rths_shooting_options *opt, rths_periodic_point **out, int *n_out,
                       rths_error *err) {
    int n = a->n, nx = 2 * n, rc = RTHS_OK;
    *out = NULL;
    *n_out = 0;
    if (count < 0 || count > RTHS_MAX_NONLINEAR)
        return rths_error_set(err, RTHS_EINPUT, "%d nonlinear elements: at most %d", count,
                              RTHS_MAX_NONLINEAR);
    for (int e = 0; e < count; e++)
        if (el[e].dof_i < 0 || el[e].dof_i >= n || el[e].dof_j < -1 || el[e].dof_j >= n ||
            el[e].dof_i == el[e].dof_j)
            return rths_error_set(err, RTHS_EINPUT, "nonlinear element %d: DoFs out of range",
                                  e + 1);
    shooter s = {
        .n = n, .nx = nx, .a = a, .count = count, .el = el, .steps = opt->steps_per_period};
    size_t cols = 2 * (size_t)n + 2 + (size_t)count;
    double *rhsm = rths_mat_new(n, (int)cols);
    double *mm = rths_mat_dup(a->mass, n, n);
    if (!rhsm || !mm) {
        free(rhsm), free(mm);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    size_t nn = (size_t)n * n;
    memcpy(rhsm, a->stiffness, nn * sizeof(double));
    memcpy(rhsm + nn, a->damping, nn * sizeof(double));
    memcpy(rhsm + 2 * nn, static_force, (size_t)n * sizeof(double));
    memcpy(rhsm + 2 * nn + n, force, (size_t)n * sizeof(double));
    double *b = rhsm + 2 * nn + 2 * n;
    for (int e = 0; e < count; e++) {
        b[el[e].dof_i + (size_t)e * n] = 1.0;
        if (el[e].dof_j >= 0) b[el[e].dof_j + (size_t)e * n] = -1.0;
    }
    if (rths_mat_solve(n, (int)cols, mm, rhsm) != 0) {
        free(rhsm), free(mm);
        return rths_error_set(err, RTHS_EINPUT, "mass matrix is singular");
    }
    free(mm);
    s.minv_k = rhsm;
    s.minv_c = rhsm + nn;
    s.minv_fs = rhsm + 2 * nn;
    s.minv_f = rhsm + 2 * nn + n;
    s.minv_b = rhsm + 2 * nn + 2 * n;
    shoot_problem p = {
        .s = &s, .m = nx + 1, .sw = 2 * M_PI * fmax(fabs(opt->end_hz - opt->start_hz), 1e-3)};
    int cap = opt->max_points, np = 0;
    rths_periodic_point *pts = calloc((size_t)cap, sizeof *pts);
    double *y = malloc((size_t)(nx + 1) * sizeof *y), *phi = rths_mat_new(nx, nx);
    if (problem_alloc(&p) || !pts || !y || !phi) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    double w0 = 2 * M_PI * opt->start_hz;
    double amp = first_guess(&s, static_force, force, w0, y, err);
    if (amp < 0) {
        rc = err ? err->code : RTHS_EFAIL;
        goto done;
    }
    for (int i = 0; i < n; i++) {
        p.sx[i] = amp;
        p.sx[n + i] = amp * w0;
    }
    for (int i = 0; i < nx; i++)
        y[i] /= p.sx[i];
    y[nx] = w0 / p.sw;
    if (shoot_newton(&p, y, NULL, NULL, phi) < 0) {
        rc = rths_error_set(err, RTHS_EFAIL, "shooting did not converge at %g Hz", opt->start_hz);
        goto done;
    }
    rc = trace(&p, opt, y, phi, pts, cap, &np, err);
done:
    if (rc) {
        rths_periodic_points_free(pts, np);
    } else {
        *out = pts;
        *n_out = np;
    }
    problem_free(&p);
    free(y), free(phi), free(rhsm);
    return rc;
}

int rths_bilinear_frf(const rths_assembly *a, const rths_bilinear_leg *leg,
                      const double *static_force, const double *force,
                      const rths_shooting_options *opt, rths_periodic_point **out, int *n_out,
                      rths_error *err) {
    rths_nl_element e = rths_nl_from_leg(leg);
    return rths_nonlinear_frf(a, 1, &e, static_force, force, opt, out, n_out, err);
}
