/* The frequency form's nonlinear numerical substructure (harmonic_balance.h,
 * rths_hb_substructure; docs/method.md, "Nonlinear elements in the frequency form").
 *
 * Unknowns: the Fourier coefficients of the kept DoFs (the interface first, then every DoF an
 * element touches), harmonics 0..H, laid out as rths_hb_solve's (coef[i + r j]). The other DoFs
 * are linear and condensed out per harmonic: with D_k = K + i k w C - (k w)^2 M, the kept DoFs
 * see S_k = D_RR - D_RL D_LL^-1 D_LR and the loads f_R - D_RL D_LL^-1 f_L, exactly. The Newton
 * matrix is the condensed linear part (built once per frequency) plus the elements' AFT Jacobian
 * (the same samples as their forces), so it is the exact Jacobian of the truncated system. */
#include "rths/harmonic_balance.h"

#include "rths/signals.h"

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct rths_hb_substructure {
    int nn, n_int, r, n_cond, H, N, nb, nu;
    int *keep, *cond;                          /* substructure indices: r kept, n_cond condensed */
    double *mass, *damping, *stiffness;        /* nn x nn copies */
    double *forcing, *static_force;            /* nn */
    int count;                                 /* numerical elements */
    rths_nl_element el[RTHS_MAX_NONLINEAR];    /* dof_i / dof_j as kept indices (-1: ground) */
    double omega;                              /* frequency of the cached linear part, rad/s */
    double *jlin, *load_forcing, *load_static; /* nu x nu, nu, nu */
    double *tab, *tab_rate;                    /* N x nb basis samples; the rates at omega */
    double *coef, *trial, *res, *jac, *step, *load; /* nu, nu, nu, nu x nu, nu, nu */
    lapack_int *ipiv;
    double complex *d, *a_ll, *b_l; /* nn x nn, n_cond x n_cond, n_cond x (r + 2) */
    double *gsum;                   /* nb x nb: one element's AFT Jacobian */
    int constrained_j;              /* the interfaces' coefficients j < this are prescribed */
    double *target, *reaction; /* n_int x nb, [d * nb + j]: their values, the force they need */
    double ground_kp[RTHS_MAX_INTERFACE_DOFS], ground_kd[RTHS_MAX_INTERFACE_DOFS]; /* in K, C */
    int have_coef, last_newton;
    long solves;
};

void rths_hb_substructure_destroy(rths_hb_substructure *h) {
    if (!h) return;
    free(h->keep), free(h->cond), free(h->mass), free(h->damping), free(h->stiffness);
    free(h->forcing), free(h->static_force), free(h->jlin), free(h->load_forcing);
    free(h->load_static), free(h->tab), free(h->tab_rate), free(h->coef), free(h->trial);
    free(h->res), free(h->jac), free(h->step), free(h->ipiv), free(h->d), free(h->a_ll);
    free(h->b_l), free(h->gsum), free(h->load);
    free(h->target), free(h->reaction);
    free(h);
}

/* substructure index of assembly DoF dof (interfaces 0..n_int - 1, then the numerical internal
 * DoFs), or -1 */
static int sub_index(const rths_split *s, int dof) {
    for (int d = 0; d < s->n_int; d++)
        if (dof == s->int_dofs[d]) return d;
    for (int i = 0; i < s->n_num; i++)
        if (s->num_dofs[i] == dof) return s->n_int + i;
    return -1;
}

static double basis(int j, double theta) {
    if (j == 0) return 1.0;
    int k = (j + 1) / 2;
    return j % 2 ? cos(k * theta) : sin(k * theta);
}

/* d basis / dt at unit circular frequency */
static double basis_rate(int j, double theta) {
    if (j == 0) return 0.0;
    int k = (j + 1) / 2;
    return j % 2 ? -k * sin(k * theta) : k * cos(k * theta);
}

int rths_hb_substructure_create(const rths_split *s, int count, const rths_nl_element *el,
                                const double *static_force, int forcing_dof,
                                const rths_hb_options *opt, rths_hb_substructure **out,
                                rths_error *err) {
    *out = NULL;
    if (s->n_int < 1 || s->n_int > RTHS_MAX_INTERFACE_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "the frequency form's nonlinear numerical substructure takes 1 to %d "
                              "interface DoFs; this split has %d",
                              RTHS_MAX_INTERFACE_DOFS, s->n_int);
    rths_hb_options o;
    rths_hb_defaults(&o);
    o.harmonics = RTHS_HB_SUBSTRUCTURE_HARMONICS;
    o.samples = RTHS_HB_SUBSTRUCTURE_SAMPLES;
    if (opt) o = *opt;
    if (o.harmonics < RTHS_MAX_HARMONICS || o.samples < 2 * o.harmonics + 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "harmonic balance of the numerical substructure: %d harmonics (at "
                              "least %d) need at least %d time samples (got %d)",
                              o.harmonics, RTHS_MAX_HARMONICS, 2 * o.harmonics + 1, o.samples);
    rths_hb_substructure *h = calloc(1, sizeof *h);
    if (!h) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    const int nn = s->nn;
    h->nn = nn;
    h->n_int = s->n_int;
    h->H = o.harmonics;
    h->N = o.samples;
    h->nb = 2 * h->H + 1;
    /* the kept DoFs: the interfaces, then each element's DoFs in order of appearance */
    int *is_kept = calloc((size_t)nn, sizeof(int));
    h->keep = malloc(sizeof(int) * (size_t)nn);
    h->cond = malloc(sizeof(int) * (size_t)nn);
    if (!is_kept || !h->keep || !h->cond) {
        free(is_kept);
        rths_hb_substructure_destroy(h);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    int *kept_at = is_kept; /* 1 + kept index, 0: condensed */
    for (int d = 0; d < s->n_int; d++) {
        h->keep[h->r++] = d;
        kept_at[d] = h->r;
    }
    int rc = RTHS_OK;
    for (int e = 0; e < count && !rc; e++) {
        if (!el[e].numerical) continue;
        rths_nl_element ne = el[e];
        int dofs[2] = {el[e].dof_i, el[e].dof_j}, sub[2] = {-1, -1};
        for (int t = 0; t < 2 && !rc; t++) {
            if (t == 1 && dofs[t] < 0) break;
            sub[t] = sub_index(s, dofs[t]);
            if (sub[t] < 0)
                rc = rths_error_set(err, RTHS_EINPUT,
                                    "nonlinear element %d (%s): DoF %d is not on the numerical "
                                    "side of the split",
                                    e + 1, rths_nl_type_name(el[e].type), dofs[t] + 1);
            else if (!kept_at[sub[t]]) {
                h->keep[h->r++] = sub[t];
                kept_at[sub[t]] = h->r;
            }
        }
        if (rc) break;
        ne.dof_i = kept_at[sub[0]] - 1;
        ne.dof_j = dofs[1] < 0 ? -1 : kept_at[sub[1]] - 1;
        h->el[h->count++] = ne;
    }
    for (int i = 0; i < nn; i++)
        if (!kept_at[i]) h->cond[h->n_cond++] = i;
    free(is_kept);
    if (rc) {
        rths_hb_substructure_destroy(h);
        return rc;
    }
    const int nb = h->nb, nu = h->r * nb, L = h->n_cond;
    h->nu = nu;
    h->mass = rths_mat_dup(s->mass_num, nn, nn);
    h->damping = rths_mat_dup(s->damping_num, nn, nn);
    h->stiffness = rths_mat_dup(s->stiffness_num, nn, nn);
    h->forcing = calloc((size_t)nn, sizeof(double));
    h->static_force = calloc((size_t)nn, sizeof(double));
    h->jlin = malloc(sizeof(double) * (size_t)nu * nu);
    h->jac = malloc(sizeof(double) * (size_t)nu * nu);
    h->load_forcing = malloc(sizeof(double) * (size_t)nu);
    h->load_static = malloc(sizeof(double) * (size_t)nu);
    h->coef = calloc((size_t)nu, sizeof(double));
    h->trial = malloc(sizeof(double) * (size_t)nu);
    h->res = malloc(sizeof(double) * (size_t)nu);
    h->step = malloc(sizeof(double) * (size_t)nu);
    h->load = malloc(sizeof(double) * (size_t)nu * 2);
    h->target = calloc((size_t)nb * s->n_int, sizeof(double));
    h->reaction = calloc((size_t)nb * s->n_int, sizeof(double));
    h->ipiv = malloc(sizeof(lapack_int) * (size_t)nu);
    h->tab = malloc(sizeof(double) * (size_t)h->N * nb);
    h->tab_rate = malloc(sizeof(double) * (size_t)h->N * nb);
    h->d = malloc(sizeof(double complex) * (size_t)nn * nn);
    h->a_ll = malloc(sizeof(double complex) * (size_t)(L > 0 ? L * L : 1));
    h->b_l = malloc(sizeof(double complex) * (size_t)(L > 0 ? L : 1) * (size_t)(h->r + 2));
    h->gsum = malloc(sizeof(double) * (size_t)nb * nb);
    if (!h->mass || !h->damping || !h->stiffness || !h->forcing || !h->static_force || !h->jlin ||
        !h->jac || !h->load_forcing || !h->load_static || !h->coef || !h->trial || !h->res ||
        !h->step || !h->load || !h->target || !h->reaction || !h->ipiv || !h->tab || !h->tab_rate ||
        !h->d || !h->a_ll || !h->b_l || !h->gsum) {
        rths_hb_substructure_destroy(h);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    int at = sub_index(s, forcing_dof);
    if (at >= 0) h->forcing[at] = 1.0;
    /* the preloads on the numerical internal DoFs; the interfaces' means are prescribed */
    for (int i = 0; static_force && i < s->n_num; i++)
        h->static_force[s->n_int + i] = static_force[s->num_dofs[i]];
    for (int m = 0; m < h->N; m++)
        for (int j = 0; j < nb; j++)
            h->tab[(size_t)m * nb + j] = basis(j, 2 * M_PI * m / h->N);
    h->omega = -1;
    *out = h;
    return RTHS_OK;
}

/* The condensed linear part and loads at omega (cached). */
static int build_linear(rths_hb_substructure *h, double omega, rths_error *err) {
    if (omega == h->omega) return RTHS_OK;
    const int nn = h->nn, r = h->r, L = h->n_cond, nb = h->nb, nu = h->nu;
    memset(h->jlin, 0, sizeof(double) * (size_t)nu * nu);
    memset(h->load_forcing, 0, sizeof(double) * (size_t)nu);
    memset(h->load_static, 0, sizeof(double) * (size_t)nu);
    for (int k = 0; k <= h->H; k++) {
        double w = k * omega;
        for (int c = 0; c < nn; c++)
            for (int i = 0; i < nn; i++) {
                size_t ic = i + (size_t)c * nn;
                h->d[ic] = h->stiffness[ic] - w * w * h->mass[ic] + I * w * h->damping[ic];
            }
        /* X = D_LL^-1 [D_LR, f_L, s_L] */
        if (L > 0) {
            for (int c = 0; c < L; c++)
                for (int i = 0; i < L; i++)
                    h->a_ll[i + (size_t)c * L] = h->d[h->cond[i] + (size_t)h->cond[c] * nn];
            for (int i = 0; i < L; i++) {
                for (int c = 0; c < r; c++)
                    h->b_l[i + (size_t)c * L] = h->d[h->cond[i] + (size_t)h->keep[c] * nn];
                h->b_l[i + (size_t)r * L] = h->forcing[h->cond[i]];
                h->b_l[i + (size_t)(r + 1) * L] = h->static_force[h->cond[i]];
            }
            if (LAPACKE_zgesv(LAPACK_COL_MAJOR, L, r + 2, h->a_ll, L, h->ipiv, h->b_l, L) != 0)
                return rths_error_set(err, RTHS_EFAIL,
                                      "harmonic balance of the numerical substructure: the DoFs "
                                      "no element touches are singular at harmonic %d of %g Hz "
                                      "(a part held only by nonlinear elements?)",
                                      k, omega / (2 * M_PI));
        }
        for (int i = 0; i < r; i++) {
            int ki = h->keep[i];
            double complex g = h->forcing[ki], st = h->static_force[ki];
            for (int l = 0; l < L; l++) {
                double complex dil = h->d[ki + (size_t)h->cond[l] * nn];
                g -= dil * h->b_l[l + (size_t)r * L];
                st -= dil * h->b_l[l + (size_t)(r + 1) * L];
            }
            for (int c = 0; c < r; c++) {
                double complex sic = h->d[ki + (size_t)h->keep[c] * nn];
                for (int l = 0; l < L; l++)
                    sic -= h->d[ki + (size_t)h->cond[l] * nn] * h->b_l[l + (size_t)c * L];
                if (k == 0) {
                    h->jlin[i + (size_t)c * nu] = creal(sic);
                    continue;
                }
                /* (Sr + i Si)(a - i b) = Fa - i Fb: cos row Sr a + Si b, sin row -Si a + Sr b */
                int rc_ = i + r * (2 * k - 1), rs = i + r * (2 * k);
                int cc = c + r * (2 * k - 1), cs = c + r * (2 * k);
                h->jlin[rc_ + (size_t)cc * nu] = creal(sic);
                h->jlin[rc_ + (size_t)cs * nu] = cimag(sic);
                h->jlin[rs + (size_t)cc * nu] = -cimag(sic);
                h->jlin[rs + (size_t)cs * nu] = creal(sic);
            }
            if (k == 0) h->load_static[i] = creal(st);
            if (k == 1) { /* the forcing amplitude cos(w t): phasor 1 */
                h->load_forcing[i + r] = creal(g);
                h->load_forcing[i + 2 * r] = -cimag(g);
            }
        }
    }
    for (int m = 0; m < h->N; m++)
        for (int j = 0; j < nb; j++)
            h->tab_rate[(size_t)m * nb + j] = omega * basis_rate(j, 2 * M_PI * m / h->N);
    h->omega = omega;
    return RTHS_OK;
}

/* residual res and Jacobian jac at c; returns the residual's largest entry */
static double evaluate(rths_hb_substructure *h, const double *c, const double *load) {
    const int r = h->r, nb = h->nb, nu = h->nu, N = h->N;
    memcpy(h->jac, h->jlin, sizeof(double) * (size_t)nu * nu);
    for (int row = 0; row < nu; row++)
        h->res[row] = -load[row];
    for (int col = 0; col < nu; col++) {
        double cc = c[col];
        if (cc == 0) continue;
        const double *jc = h->jlin + (size_t)col * nu;
        for (int row = 0; row < nu; row++)
            h->res[row] += jc[row] * cc;
    }
    for (int e = 0; e < h->count; e++) {
        const rths_nl_element *ne = &h->el[e];
        const double *t = rths_nl_on_rate(ne) ? h->tab_rate : h->tab;
        int di = ne->dof_i, dj = ne->dof_j;
        memset(h->gsum, 0, sizeof(double) * (size_t)nb * nb);
        for (int m = 0; m < N; m++) {
            const double *bm = t + (size_t)m * nb, *bf = h->tab + (size_t)m * nb;
            double y = 0;
            for (int j = 0; j < nb; j++)
                y += bm[j] * (c[di + r * j] - (dj >= 0 ? c[dj + r * j] : 0.0));
            double slope, g = rths_nl_force(ne, y, &slope);
            for (int j = 0; j < nb; j++) {
                double wj = (j == 0 ? 1.0 : 2.0) / N * bf[j];
                double fg = wj * g;
                h->res[di + r * j] += fg;
                if (dj >= 0) h->res[dj + r * j] -= fg;
                if (slope == 0) continue;
                double ws = wj * slope;
                double *gcol = h->gsum + j;
                for (int l = 0; l < nb; l++)
                    gcol[(size_t)l * nb] += ws * bm[l];
            }
        }
        for (int l = 0; l < nb; l++)
            for (int j = 0; j < nb; j++) {
                double d = h->gsum[j + (size_t)l * nb];
                if (d == 0) continue;
                h->jac[(di + r * j) + (size_t)(di + r * l) * nu] += d;
                if (dj >= 0) {
                    h->jac[(di + r * j) + (size_t)(dj + r * l) * nu] -= d;
                    h->jac[(dj + r * j) + (size_t)(di + r * l) * nu] -= d;
                    h->jac[(dj + r * j) + (size_t)(dj + r * l) * nu] += d;
                }
            }
    }
    /* the prescribed interface coefficients (the mean, and in rths_hb_substructure_force the
     * harmonics given): their rows become the constraints c = target; what the equations ask
     * there is the interface force the motion needs (the reaction) */
    for (int d = 0; d < h->n_int; d++)
        for (int j = 0; j < h->constrained_j; j++) {
            int row = d + r * j;
            h->reaction[d * nb + j] = h->res[row];
            h->res[row] = c[row] - h->target[d * nb + j];
            for (int col = 0; col < nu; col++)
                h->jac[row + (size_t)col * nu] = col == row;
        }
    double worst = 0;
    for (int row = 0; row < nu; row++)
        worst = fmax(worst, fabs(h->res[row]));
    return worst;
}

static double norm2(const double *v, int n) {
    double sum = 0;
    for (int i = 0; i < n; i++)
        sum += v[i] * v[i];
    return sqrt(sum);
}

/* Newton from h->coef, plain or (damped) with a backtracking line search on the residual's
 * 2-norm; 1 when the largest entry reaches tol. Plain Newton first: on the kink's piecewise-linear
 * residual it takes 2-3 steps where the damped one crawls (measured on the bilinear example). */
static int newton(rths_hb_substructure *h, const double *load, double tol, int max_steps,
                  int damped, int *steps) {
    const int nu = h->nu;
    double worst = evaluate(h, h->coef, load), merit = norm2(h->res, nu);
    for (int it = 0; it <= max_steps; it++) {
        *steps += it > 0;
        if (!isfinite(worst)) return 0;
        if (worst <= tol) return 1;
        if (it == max_steps) return 0;
        memcpy(h->step, h->res, sizeof(double) * (size_t)nu);
        if (LAPACKE_dgesv(LAPACK_COL_MAJOR, nu, 1, h->jac, nu, h->ipiv, h->step, nu) != 0) return 0;
        double lambda = 1, next = worst, next_merit = merit;
        for (int half = 0; half < 12; half++, lambda *= 0.5) {
            for (int i = 0; i < nu; i++)
                h->trial[i] = h->coef[i] - lambda * h->step[i];
            next = evaluate(h, h->trial, load);
            next_merit = norm2(h->res, nu);
            if (!damped || next_merit < (1 - 1e-4 * lambda) * merit) break;
        }
        if (damped && !(next_merit < merit)) return 0; /* no descent: a homotopy takes over */
        memcpy(h->coef, h->trial, sizeof(double) * (size_t)nu);
        worst = next;
        merit = next_merit;
    }
    return 0;
}

/* Newton homotopy from h->coef (a solution of nearby data): R(c) = (1 - tau) R(c_start), tau
 * raised from 0 to 1 in steps that halve when a corrector fails; 1 when tau reached 1. */
static int homotopy(rths_hb_substructure *h, const double *load, double tol, int *steps) {
    const int nu = h->nu, nb = h->nb;
    const int nc = h->n_int * nb;
    double *shifted = malloc(sizeof(double) * (size_t)(nu * 3 + nc));
    if (!shifted) return 0;
    double *r0 = shifted + nu, *saved = shifted + 2 * nu, *target = shifted + 3 * nu;
    evaluate(h, h->coef, load);
    memcpy(r0, h->res, sizeof(double) * (size_t)nu);
    memcpy(target, h->target, sizeof(double) * (size_t)nc);
    double tau = 0, dtau = 0.125;
    int ok = 1;
    while (tau < 1 && ok) {
        double next = fmin(1.0, tau + dtau);
        for (int i = 0; i < nu; i++)
            shifted[i] = load[i] + (1 - next) * r0[i];
        for (int d = 0; d < h->n_int; d++) /* a constraint's row is c - target */
            for (int j = 0; j < h->constrained_j; j++)
                h->target[d * nb + j] = target[d * nb + j] + (1 - next) * r0[d + h->r * j];
        memcpy(saved, h->coef, sizeof(double) * (size_t)nu);
        if (newton(h, shifted, tol, 30, 0, steps) || newton(h, shifted, tol, 30, 1, steps)) {
            tau = next;
            dtau = fmin(0.25, 1.5 * dtau);
        } else {
            memcpy(h->coef, saved, sizeof(double) * (size_t)nu);
            dtau *= 0.5;
            ok = dtau > 1e-4;
        }
    }
    memcpy(h->target, target, sizeof(double) * (size_t)nc);
    free(shifted);
    return ok;
}

/* Newton (then homotopies) on the loads h->load and the constraints h->target */
static int solve_loaded(rths_hb_substructure *h, double omega, double scale, rths_error *err) {
    const int nu = h->nu;
    const double *load = h->load;
    double tol = 1e-10 * (scale > 0 ? scale : 1.0);
    /* from the previous solution; failing that, by homotopy from it; failing that (or with no
     * previous solution), from rest (its first step is the linear response) */
    int steps = 0, ok = 0;
    double *start = h->load + nu; /* the starting point, kept for the retries */
    if (h->have_coef) {
        memcpy(start, h->coef, sizeof(double) * (size_t)nu);
        ok = newton(h, load, tol, 20, 0, &steps);
        if (!ok) memcpy(h->coef, start, sizeof(double) * (size_t)nu);
        if (!ok) ok = newton(h, load, tol, 50, 1, &steps);
        if (!ok) memcpy(h->coef, start, sizeof(double) * (size_t)nu);
        if (!ok) ok = homotopy(h, load, tol, &steps);
    }
    if (!ok) {
        memset(h->coef, 0, sizeof(double) * (size_t)nu);
        ok = newton(h, load, tol, 20, 0, &steps);
        if (!ok) memset(h->coef, 0, sizeof(double) * (size_t)nu);
        ok = ok || newton(h, load, tol, 100, 1, &steps) || homotopy(h, load, tol, &steps);
    }
    h->last_newton = steps;
    h->solves++;
    h->have_coef = ok;
    if (!ok)
        return rths_error_set(err, RTHS_EFAIL,
                              "harmonic balance of the numerical substructure did not converge at "
                              "%g Hz (%d harmonics, %d time samples)",
                              omega / (2 * M_PI), h->H, h->N);
    return RTHS_OK;
}

int rths_hb_substructure_solve(rths_hb_substructure *h, double omega_rad_s, double amplitude_n,
                               int n_harmonics, const double *force_a, const double *force_b,
                               double mean_m, double *disp_a, double *disp_b, double *sensitivity,
                               rths_error *err) {
    const int r = h->r, nu = h->nu, H = h->H;
    if (h->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "the force-driven numerical substructure takes one interface DoF "
                              "(this one has %d)",
                              h->n_int);
    if (!(omega_rad_s > 0) || n_harmonics < 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "harmonic balance of the numerical substructure: frequency %g rad/s "
                              "and %d harmonics (positive both)",
                              omega_rad_s, n_harmonics);
    int rc = build_linear(h, omega_rad_s, err);
    if (rc) return rc;
    /* the loads: static, the forcing, the interface force's harmonics, the interface's mean */
    double *loadbuf = h->load;
    double scale = fabs(amplitude_n);
    for (int i = 0; i < nu; i++) {
        loadbuf[i] = h->load_static[i] + amplitude_n * h->load_forcing[i];
        scale = fmax(scale, fabs(h->load_static[i]));
    }
    for (int k = 1; k <= n_harmonics && k <= H; k++) {
        loadbuf[r * (2 * k - 1)] += force_a[k];
        loadbuf[r * (2 * k)] += force_b[k];
        scale = fmax(scale, fmax(fabs(force_a[k]), fabs(force_b[k])));
    }
    h->constrained_j = 1;
    h->target[0] = mean_m;
    rc = solve_loaded(h, omega_rad_s, scale, err);
    if (rc) return rc;
    disp_a[0] = mean_m;
    disp_b[0] = 0;
    for (int k = 1; k <= n_harmonics; k++) {
        disp_a[k] = k <= H ? h->coef[r * (2 * k - 1)] : 0;
        disp_b[k] = k <= H ? h->coef[r * (2 * k)] : 0;
    }
    if (sensitivity) {
        /* d coef / d F = J^-1 e_row (the force enters the residual as -F) at the solution */
        const int n2 = 2 * n_harmonics;
        memset(sensitivity, 0, sizeof(double) * (size_t)n2 * n2);
        evaluate(h, h->coef, loadbuf);
        if (LAPACKE_dgetrf(LAPACK_COL_MAJOR, nu, nu, h->jac, nu, h->ipiv) != 0) {
            return rths_error_set(err, RTHS_EFAIL,
                                  "harmonic balance of the numerical substructure: singular "
                                  "Jacobian at %g Hz",
                                  omega_rad_s / (2 * M_PI));
        }
        for (int col = 0; col < n2; col++) {
            int k = col % n_harmonics + 1, sin_term = col >= n_harmonics;
            if (k > H) continue;
            memset(h->step, 0, sizeof(double) * (size_t)nu);
            h->step[r * (2 * k - 1 + sin_term)] = 1;
            LAPACKE_dgetrs(LAPACK_COL_MAJOR, 'N', nu, 1, h->jac, nu, h->ipiv, h->step, nu);
            for (int row = 0; row < n2; row++) {
                int kr = row % n_harmonics + 1, sr = row >= n_harmonics;
                if (kr <= H) sensitivity[row + (size_t)col * n2] = h->step[r * (2 * kr - 1 + sr)];
            }
        }
    }
    return RTHS_OK;
}

int rths_hb_substructure_set_grounding(rths_hb_substructure *h, const double *kp_n_per_m,
                                       const double *kd_n_s_per_m, rths_error *err) {
    const int nn = h->nn;
    for (int d = 0; d < h->n_int; d++) {
        if (!(kp_n_per_m[d] >= 0) || !(kd_n_s_per_m[d] >= 0))
            return rths_error_set(err, RTHS_EINPUT,
                                  "grounding of interface DoF %d: gains %g and %g (not negative)",
                                  d + 1, kp_n_per_m[d], kd_n_s_per_m[d]);
        h->stiffness[d + (size_t)d * nn] += kp_n_per_m[d] - h->ground_kp[d];
        h->damping[d + (size_t)d * nn] += kd_n_s_per_m[d] - h->ground_kd[d];
        h->ground_kp[d] = kp_n_per_m[d];
        h->ground_kd[d] = kd_n_s_per_m[d];
    }
    h->omega = -1; /* the linear part changed */
    return RTHS_OK;
}

int rths_hb_substructure_solve_dofs(rths_hb_substructure *h, double omega_rad_s, double amplitude_n,
                                    const rths_fourier *force, const rths_fourier *base,
                                    rths_fourier *disp, rths_error *err) {
    const int r = h->r, nu = h->nu, H = h->H, nb = h->nb, ni = h->n_int;
    if (!(omega_rad_s > 0))
        return rths_error_set(err, RTHS_EINPUT,
                              "harmonic balance of the numerical substructure: frequency %g rad/s "
                              "(positive)",
                              omega_rad_s);
    int rc = build_linear(h, omega_rad_s, err);
    if (rc) return rc;
    double scale = fabs(amplitude_n);
    for (int i = 0; i < nu; i++) {
        h->load[i] = h->load_static[i] + amplitude_n * h->load_forcing[i];
        scale = fmax(scale, fabs(h->load_static[i]));
    }
    /* the interface forces and the grounding's pull toward the base motion,
     * kp x + kd x' = (kp a + kd k w b) cos + (kp b - kd k w a) sin */
    for (int d = 0; d < ni; d++)
        for (int k = 1; k <= RTHS_MAX_HARMONICS && k <= H; k++) {
            double kw = k * omega_rad_s, a = base[d].a[k], b = base[d].b[k];
            double fc = force[d].a[k] + h->ground_kp[d] * a + h->ground_kd[d] * kw * b;
            double fs = force[d].b[k] + h->ground_kp[d] * b - h->ground_kd[d] * kw * a;
            h->load[d + r * (2 * k - 1)] += fc;
            h->load[d + r * (2 * k)] += fs;
            scale = fmax(scale, fmax(fabs(fc), fabs(fs)));
        }
    /* every interface's mean prescribed (the base's) */
    h->constrained_j = 1;
    for (int d = 0; d < ni; d++)
        h->target[(size_t)d * nb] = base[d].a[0];
    rc = solve_loaded(h, omega_rad_s, scale, err);
    if (rc) return rc;
    for (int d = 0; d < ni; d++) {
        memset(&disp[d], 0, sizeof disp[d]);
        disp[d].a[0] = base[d].a[0];
        for (int k = 1; k <= RTHS_MAX_HARMONICS && k <= H; k++) {
            disp[d].a[k] = h->coef[d + r * (2 * k - 1)];
            disp[d].b[k] = h->coef[d + r * (2 * k)];
        }
    }
    return RTHS_OK;
}

int rths_hb_substructure_force(rths_hb_substructure *h, double omega_rad_s, double amplitude_n,
                               int n_harmonics, const double *disp_a, const double *disp_b,
                               double *force_a, double *force_b, rths_error *err) {
    const int r = h->r, nu = h->nu, H = h->H;
    if (h->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "rths_hb_substructure_force takes one interface DoF (this one has "
                              "%d): use rths_hb_substructure_force_dofs",
                              h->n_int);
    if (!(omega_rad_s > 0) || n_harmonics < 1 || n_harmonics > H)
        return rths_error_set(err, RTHS_EINPUT,
                              "harmonic balance of the numerical substructure: frequency %g rad/s "
                              "(positive) and %d harmonics (1..%d)",
                              omega_rad_s, n_harmonics, H);
    int rc = build_linear(h, omega_rad_s, err);
    if (rc) return rc;
    double scale = fabs(amplitude_n);
    for (int i = 0; i < nu; i++) {
        h->load[i] = h->load_static[i] + amplitude_n * h->load_forcing[i];
        scale = fmax(scale, fabs(h->load_static[i]));
    }
    /* the interface's mean and harmonics 1..n_harmonics prescribed; above them it is free of
     * force */
    h->constrained_j = 2 * n_harmonics + 1;
    h->target[0] = disp_a[0];
    for (int k = 1; k <= n_harmonics; k++) {
        h->target[2 * k - 1] = disp_a[k];
        h->target[2 * k] = disp_b[k];
    }
    /* the force scale: the linear part's at the prescribed motion */
    double motion = 0;
    for (int j = 1; j < h->constrained_j; j++)
        motion = fmax(motion, fabs(h->target[j]));
    scale = fmax(scale, motion * fabs(h->jlin[r + (size_t)r * nu]));
    rc = solve_loaded(h, omega_rad_s, scale, err);
    if (!rc) {
        evaluate(h, h->coef, h->load); /* the reactions at the solution */
        force_a[0] = h->reaction[0];
        force_b[0] = 0;
        for (int k = 1; k <= n_harmonics; k++) {
            force_a[k] = h->reaction[2 * k - 1];
            force_b[k] = h->reaction[2 * k];
        }
    }
    h->constrained_j = 1;
    return rc;
}

int rths_hb_substructure_eval(void *ctx, double omega_rad_s, double complex *receptance_m_per_n,
                              double complex *forced_m_per_n, rths_error *err) {
    rths_hb_substructure *h = ctx;
    const int nn = h->nn;
    if (h->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "the substructure's receptance takes one interface DoF (this one has "
                              "%d)",
                              h->n_int);
    double *unit = calloc((size_t)nn, sizeof(double));
    double complex *x = malloc(sizeof(double complex) * (size_t)nn);
    int rc = unit && x ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) unit[0] = 1;
    if (!rc) rc = rths_frf(nn, h->mass, h->damping, h->stiffness, unit, omega_rad_s, x, err);
    if (!rc) *receptance_m_per_n = x[0];
    if (!rc) rc = rths_frf(nn, h->mass, h->damping, h->stiffness, h->forcing, omega_rad_s, x, err);
    if (!rc) *forced_m_per_n = x[0];
    free(unit), free(x);
    return rc;
}

void rths_hb_substructure_describe(const rths_hb_substructure *h, char *buf, size_t size) {
    snprintf(buf, size,
             "harmonic balance of the numerical substructure: %d harmonics, %d time samples per "
             "period (AFT), %d DoF(s) kept (interface + elements' DoFs), %d condensed, %d "
             "element(s)",
             h->H, h->N, h->r, h->n_cond, h->count);
}

void rths_hb_substructure_counts(const rths_hb_substructure *h, int *last_newton, long *solves) {
    if (last_newton) *last_newton = h->last_newton;
    if (solves) *solves = h->solves;
}
