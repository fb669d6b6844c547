/* Fold detection and location along the branch (sign change of the frequency component of the
 * secant, confirmed beyond the points' frequency scatter), and the branch segments between folds.
 */
#include "continuation/continuation_internal.h"

#include <math.h>

static double dist(const double *a, const double *b, int m) {
    double s = 0;
    for (int i = 0; i < m; i++)
        s += (a[i] - b[i]) * (a[i] - b[i]);
    return sqrt(s);
}

/* Vertex of the parabola through (s_i, w_i), i = 0..2; returns 0 if not a proper extremum. */
static int parabola_vertex(const double *s, const double *w, double *s_star) {
    double d01 = (w[1] - w[0]) / (s[1] - s[0]), d12 = (w[2] - w[1]) / (s[2] - s[1]);
    double a = (d12 - d01) / (s[2] - s[0]);
    if (!(fabs(a) > 0)) return 0;
    double b = d01 - a * (s[0] + s[1]);
    *s_star = -b / (2 * a);
    return *s_star >= s[0] && *s_star <= s[2];
}

/* Locates the fold around the extreme point e (frequency and amplitude at the parabola's vertex
 * in arclength, by Lagrange interpolation); returns the point after which it lies. */
static int locate_fold(const cont_run *run, int e, rths_fold *fold) {
    const rths_point *pts = run->pts;
    const double *svals = run->folds.svals;
    double s3[3] = {svals[e - 1], svals[e], svals[e + 1]};
    double w3[3] = {pts[e - 1].sol.omega_rad_s, pts[e].sol.omega_rad_s, pts[e + 1].sol.omega_rad_s};
    double a3[3] = {rths_point_amplitude_m(&pts[e - 1]), rths_point_amplitude_m(&pts[e]),
                    rths_point_amplitude_m(&pts[e + 1])};
    double s_star = s3[1];
    if (!parabola_vertex(s3, w3, &s_star)) s_star = s3[1];
    double w_star = 0, a_star = 0;
    for (int i = 0; i < 3; i++) {
        double l = 1;
        for (int j = 0; j < 3; j++)
            if (j != i) l *= (s_star - s3[j]) / (s3[i] - s3[j]);
        w_star += l * w3[i];
        a_star += l * a3[i];
    }
    int after = s_star < s3[1] ? e - 1 : e;
    *fold = (rths_fold){w_star / (2 * M_PI), a_star, after};
    return after;
}

/* A fold was found around the extreme e with point n the newest: mark it, start a new segment,
 * re-report the changed points, and look for the new extreme in the reversed direction. */
static int mark_fold(cont_run *run, int e, int n, int notify) {
    cont_fold_tracker *ft = &run->folds;
    rths_fold fold;
    int after = locate_fold(run, e, &fold), status = RTHS_OK;
    run->pts[after].fold = 1;
    ft->segment++;
    for (int q = after + 1; q <= n; q++)
        run->pts[q].segment = ft->segment;
    if (run->res->n_folds < 32) run->res->folds[run->res->n_folds++] = fold;
    if (notify && run->on_point)
        for (int q = after; q < n && status == RTHS_OK; q++)
            status = run->on_point(run->user, &run->pts[q], 1);
    ft->wdir = -ft->wdir;
    ft->ext_idx = n;
    for (int q = e + 1; q <= n; q++)
        if (ft->wdir * (run->pts[q].sol.omega_rad_s - run->pts[ft->ext_idx].sol.omega_rad_s) > 0)
            ft->ext_idx = q;
    return status;
}

/* The scatter of the points' frequencies (scaled) about the branch near a candidate fold, from
 * the points first..n: each inner point's offset from the chord through its neighbours in
 * arclength, r_i = w_i - (w_{i-1} (s_{i+1} - s_i) + w_{i+1} (s_i - s_{i-1})) / (s_{i+1} -
 * s_{i-1}). For independent frequency errors of standard deviation sigma, var r_i = sigma^2 (1 +
 * a^2 + b^2) >= 1.5 sigma^2 (a + b = 1); the branch's own curvature only adds to r, so the
 * estimate errs large. Local, because the frequency's scatter is: the corrector accepts each
 * point within a noisy mismatch, and where the branch stands vertical (at a fold) that mismatch
 * is all frequency. Returns 0 with fewer than 3 inner points. */
static double frequency_scatter(const cont_run *run, int first, int n) {
    const double *s = run->folds.svals;
    int count = 0;
    double sum = 0.0;
    for (int i = first > 1 ? first : 1; i < n; i++) {
        double h = s[i + 1] - s[i - 1];
        if (!(h > 0)) continue;
        double a = (s[i + 1] - s[i]) / h, b = (s[i] - s[i - 1]) / h;
        double w_prev = run->pts[i - 1].sol.omega_rad_s, w_next = run->pts[i + 1].sol.omega_rad_s;
        double off =
            (run->pts[i].sol.omega_rad_s - (a * w_prev + b * w_next)) / run->sc.omega_scale;
        sum += off * off;
        count++;
    }
    return count >= 3 ? sqrt(sum / count / 1.5) : 0.0;
}

/* Points before the extreme whose scatter joins the estimate (with those after it). */
enum { FOLD_SCATTER_POINTS_BEFORE = 4 };

/* A reversal of the frequency is a fold only when the branch has come back from its extreme by
 * more than the points' frequency scatter can make: three standard deviations of the difference
 * of two points' errors. Below that the extreme stays open, and a later point beyond it moves
 * it on (noise near a vertical fold made the Duffing example report six folds for two). */
static const double FOLD_REVERSAL_SIGMAS = 3.0;

int cont_fold_track(cont_run *run, int n, int notify) {
    cont_fold_tracker *ft = &run->folds;
    rths_point *pt = &run->pts[n];
    pt->segment = ft->segment;
    if (n == 0) return RTHS_OK;
    double u0[CONT_LD], u1[CONT_LD];
    int m = cont_pack(&run->sc, &run->pts[n - 1].sol, u0);
    cont_pack(&run->sc, &pt->sol, u1);
    ft->svals[n] = ft->svals[n - 1] + dist(u0, u1, m);
    if (n == 1) {
        ft->wdir = pt->secant_omega >= 0 ? 1 : -1;
        ft->ext_idx = 1;
        return RTHS_OK;
    }
    double w = pt->sol.omega_rad_s / run->sc.omega_scale;
    double w_ext = run->pts[ft->ext_idx].sol.omega_rad_s / run->sc.omega_scale;
    double margin = 0.05 * fmax(pt->step, run->opt->min_step);
    if (ft->wdir * (w_ext - w) > margin)
        margin =
            fmax(margin, FOLD_REVERSAL_SIGMAS * sqrt(2.0) *
                             frequency_scatter(run, ft->ext_idx - FOLD_SCATTER_POINTS_BEFORE, n));
    if (ft->wdir * (w - w_ext) > 0) {
        ft->ext_idx = n;
        return RTHS_OK;
    }
    /* the point before must be back beyond the margin too: one stray point is not a turn */
    double w_prev = run->pts[n - 1].sol.omega_rad_s / run->sc.omega_scale;
    if (ft->wdir * (w_ext - w) > margin && ft->wdir * (w_ext - w_prev) > margin &&
        ft->ext_idx >= 1 && ft->ext_idx < n - 1)
        return mark_fold(run, ft->ext_idx, n, notify);
    return RTHS_OK;
}
