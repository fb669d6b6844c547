/* Stability chart over (tau, p): per p row, one spectral labelling at the smallest delay, roots
 * followed along tau, the critical delay located where the rightmost root crosses, boundaries by
 * MDBM, and a cross-check of labels against boundaries. Rows run in parallel (OpenMP); each row
 * writes only its own slots, so the output does not depend on the thread count. */
#include "stability_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* OpenBLAS's own threads fight OpenMP's when LAPACK runs inside the parallel rows (3-4x slower
 * on two cores); its control functions are bound weakly so another BLAS still links. */
void openblas_set_num_threads(int n) __attribute__((weak));
int openblas_get_num_threads(void) __attribute__((weak));

void rths_chart_options_default(rths_chart_options *o) {
    memset(o, 0, sizeof *o);
    o->tau_min_s = 5e-5;
    o->tau_max_s = 3e-4;
    o->tau_points = 200;
    o->p_min = 0.01;
    o->p_max = 0.99;
    o->p_points = 200;
    o->omega_min_rad_s = 1e-4;
    o->omega_max_rad_s = 550.0;
    o->omega_points = 111;
    o->mdbm_tau_points = 50;
    o->mdbm_p_points = 50;
    o->mdbm_refine = 3;
    o->chebyshev_nodes = 12;
}

void rths_chart_free(rths_chart *c) {
    if (!c) return;
    free(c->tau);
    free(c->p);
    free(c->max_real);
    free(c->stable);
    free(c->essential_rate_times_tau);
    free(c->critical_tau);
    free(c->critical_omega);
    free(c->b_tau);
    free(c->b_p);
    free(c->b_omega);
    free(c->b_curve);
    memset(c, 0, sizeof *c);
}

int rths_split_family_build(void *ctx, double p, rths_dde *out, rths_error *err) {
    const rths_split_family *f = ctx;
    rths_split s;
    int rc = rths_split_create(f->assembly, f->roles, p, f->damping_int_phys, f->stiffness_int_phys,
                               &s, err);
    if (rc) return rc;
    rc = rths_dde_from_split(f->assembly, &s, out, err);
    rths_split_free(&s);
    return rc;
}

static int check_options(const rths_chart_options *o, rths_error *err) {
    if (!(o->tau_min_s > 0 && o->tau_max_s > o->tau_min_s && isfinite(o->tau_max_s)))
        return rths_error_set(err, RTHS_EINPUT, "chart: need 0 < tau_min < tau_max");
    if (!(o->p_max >= o->p_min) || !isfinite(o->p_min) || !isfinite(o->p_max))
        return rths_error_set(err, RTHS_EINPUT, "chart: need p_min <= p_max");
    if (o->tau_points < 2 || o->p_points < 1)
        return rths_error_set(err, RTHS_EINPUT, "chart: need tau_points >= 2 and p_points >= 1");
    if (!(o->omega_max_rad_s > o->omega_min_rad_s && o->omega_min_rad_s >= 0))
        return rths_error_set(err, RTHS_EINPUT, "chart: need 0 <= omega_min < omega_max");
    if (o->omega_points < 2 || o->mdbm_refine < 0 || o->mdbm_refine > 10)
        return rths_error_set(err, RTHS_EINPUT, "chart: need omega_points >= 2, mdbm_refine 0..10");
    if (o->chebyshev_nodes < 2 || o->chebyshev_nodes > 400)
        return rths_error_set(err, RTHS_EINPUT, "chart: chebyshev_nodes must be in [2, 400]");
    return RTHS_OK;
}

typedef struct row_status {
    int rc;
    rths_error err;
} row_status;

/* One p row: labels along tau and the critical delay. */
static int chart_row(rths_dde_family_fn family, void *ctx, const rths_chart_options *o,
                     rths_chart *c, int j, rths_error *err) {
    rths_dde d;
    int rc = family(ctx, c->p[j], &d, err);
    if (rc) return rc;
    double rt;
    if ((rc = rths_dde_essential(&d, &rt, NULL, NULL, err))) {
        rths_dde_free(&d);
        return rc;
    }
    c->essential_rate_times_tau[j] = rt;
    rths_tracker t = {0};
    if ((rc = rths_tracker_seed(&t, &d, c->tau[0], o->chebyshev_nodes, err))) {
        rths_dde_free(&d);
        return rc;
    }
    double crit = NAN, crit_w = NAN;
    double prev_re = 0, prev_tau = 0;
    int prev_stable = 0;
    for (int i = 0; i < c->nt && !rc; i++) {
        double tau = c->tau[i];
        if (i > 0 && (rc = rths_tracker_step(&t, tau, err))) break;
        double im, re = rths_tracker_max_real(&t, &im);
        double ess = rt / tau;
        int stable = re < 0 && ess < 0;
        size_t k = (size_t)i + (size_t)j * (size_t)c->nt;
        c->max_real[k] = fmax(re, ess);
        c->stable[k] = stable;
        if (i > 0 && prev_stable && !stable && isnan(crit) && ess < 0)
            rths_locate_crossing(&d, prev_tau, prev_re, tau, re, im, &crit, &crit_w);
        prev_re = re, prev_tau = tau, prev_stable = stable;
    }
    rths_tracker_free(&t);
    if (!rc && isnan(crit)) {
        if (rt >= 0) {
            crit = 0.0; /* unstable for every delay */
        } else if (!c->stable[(size_t)j * (size_t)c->nt]) {
            /* unstable at tau_min: look below it */
            rc = rths_dde_critical_delay(&d, c->tau[0] * 1e-3, c->tau[0], 300, o->chebyshev_nodes,
                                         &crit, &crit_w, err);
        } else {
            /* stable across the chart: look up to ten times further */
            rc = rths_dde_critical_delay(&d, c->tau[c->nt - 1], 10 * c->tau[c->nt - 1], 200,
                                         o->chebyshev_nodes, &crit, &crit_w, err);
        }
    }
    c->critical_tau[j] = crit;
    c->critical_omega[j] = crit_w;
    rths_dde_free(&d);
    return rc;
}

static void cross_check(rths_chart *c) {
    int nt = c->nt, np = c->np;
    double dt = (c->tau[nt - 1] - c->tau[0]) / (nt - 1);
    double dp = np > 1 ? (c->p[np - 1] - c->p[0]) / (np - 1) : 1.0;
    c->label_changes = c->label_changes_unexplained = c->boundary_unexplained = 0;
    /* label change along tau or p: a boundary point must lie within 1.5 cells of the midpoint,
     * unless the change is the essential spectrum's (its sign differs between the two points) */
    for (int j = 0; j < np; j++)
        for (int i = 0; i < nt; i++)
            for (int dir = 0; dir < 2; dir++) {
                int i2 = i + (dir == 0), j2 = j + (dir == 1);
                if (i2 >= nt || j2 >= np) continue;
                int s1 = c->stable[i + j * nt], s2 = c->stable[i2 + j2 * nt];
                if (s1 == s2) continue;
                double e1 = c->essential_rate_times_tau[j], e2 = c->essential_rate_times_tau[j2];
                if ((e1 < 0) != (e2 < 0)) continue;
                c->label_changes++;
                double tm = 0.5 * (c->tau[i] + c->tau[i2]), pm = 0.5 * (c->p[j] + c->p[j2]);
                int found = 0;
                for (int b = 0; b < c->n_boundary && !found; b++)
                    found = fabs(c->b_tau[b] - tm) <= 1.5 * dt && fabs(c->b_p[b] - pm) <= 1.5 * dp;
                if (!found) c->label_changes_unexplained++;
            }
    /* a boundary point strictly inside the stable region (all four surrounding labels stable) */
    for (int b = 0; b < c->n_boundary; b++) {
        int i = (int)floor((c->b_tau[b] - c->tau[0]) / dt);
        int j = np > 1 ? (int)floor((c->b_p[b] - c->p[0]) / dp) : 0;
        if (i < 0 || j < 0 || i + 1 >= nt || j + 1 >= np) continue;
        int all = 1;
        for (int a = 0; a <= 1; a++)
            for (int e = 0; e <= 1; e++)
                all &= c->stable[(i + a) + (j + e) * nt];
        /* only deep inside: the neighbours one further out must be stable too */
        if (all && i >= 1 && j >= 1 && i + 2 < nt && j + 2 < np)
            all &= c->stable[(i - 1) + j * nt] && c->stable[(i + 2) + j * nt] &&
                   c->stable[i + (j - 1) * nt] && c->stable[i + (j + 2) * nt];
        else
            all = 0;
        if (all) c->boundary_unexplained++;
    }
}

int rths_chart_compute(rths_dde_family_fn family, void *ctx, const rths_chart_options *o,
                       rths_chart *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    int rc = check_options(o, err);
    if (rc) return rc;
    int nt = o->tau_points, np = o->p_points;
    out->nt = nt;
    out->np = np;
    out->tau = malloc((size_t)nt * sizeof(double));
    out->p = malloc((size_t)np * sizeof(double));
    out->max_real = malloc((size_t)nt * (size_t)np * sizeof(double));
    out->stable = calloc((size_t)nt * (size_t)np, sizeof(int));
    out->essential_rate_times_tau = malloc((size_t)np * sizeof(double));
    out->critical_tau = malloc((size_t)np * sizeof(double));
    out->critical_omega = malloc((size_t)np * sizeof(double));
    row_status *st = calloc((size_t)np, sizeof *st);
    if (!out->tau || !out->p || !out->max_real || !out->stable || !out->essential_rate_times_tau ||
        !out->critical_tau || !out->critical_omega || !st) {
        free(st);
        rths_chart_free(out);
        return rths_error_set(err, RTHS_EFAIL, "out of memory (chart)");
    }
    for (int i = 0; i < nt; i++)
        out->tau[i] = o->tau_min_s + (o->tau_max_s - o->tau_min_s) * i / (nt - 1);
    for (int j = 0; j < np; j++)
        out->p[j] = np > 1 ? o->p_min + (o->p_max - o->p_min) * j / (np - 1) : o->p_min;
    int done = 0;
    int blas_threads = openblas_get_num_threads ? openblas_get_num_threads() : 0;
    if (openblas_set_num_threads && blas_threads > 1) openblas_set_num_threads(1);
#pragma omp parallel for schedule(dynamic)
    for (int j = 0; j < np; j++) {
        st[j].rc = chart_row(family, ctx, o, out, j, &st[j].err);
        if (o->progress) {
            int now;
#pragma omp atomic capture
            now = ++done;
            fprintf(stderr, "\rchart: %d/%d mass ratios", now, np);
        }
    }
    if (o->progress) fprintf(stderr, "\n");
    for (int j = 0; j < np; j++)
        if (st[j].rc) {
            if (err) *err = st[j].err;
            rc = st[j].rc;
            break;
        }
    free(st);
    if (!rc) rc = rths_mdbm_boundaries(family, ctx, o, out, err);
    if (openblas_set_num_threads && blas_threads > 1) openblas_set_num_threads(blas_threads);
    if (rc) {
        rths_chart_free(out);
        return rc;
    }
    cross_check(out);
    return RTHS_OK;
}
