/* Natural and pseudo-arclength continuation in forcing frequency, with fold location. */
#include "rths/continuation.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void rths_continuation_defaults(rths_continuation_options *opt) {
    memset(opt, 0, sizeof *opt);
    opt->start_hz = 12.0;
    opt->end_hz = 14.0;
    opt->method = RTHS_CONT_ARCLENGTH;
    opt->initial_step_hz = 0.05;
    opt->max_step_hz = 0.1;
    opt->min_step = 1e-4;
    opt->max_step = 0.04;
    opt->grow = 1.1;
    opt->shrink = 0.5;
    opt->max_points = 500;
    opt->max_failures = 6;
    opt->amplitude_scale_m = 0.0;
    opt->model_predictor = 1;
}

double rths_point_amplitude_m(const rths_point *pt) {
    return hypot(pt->sol.eval.phys.a[1], pt->sol.eval.phys.b[1]);
}

typedef struct {
    const rths_continuation_options *opt;
    double amp_scale, omega_scale;
    int harmonics;
} scaling;

static int pack_point(const scaling *sc, const rths_solution *s, double *u) {
    int N = sc->harmonics;
    for (int k = 0; k < N; k++) {
        u[k] = s->target_a[k] / sc->amp_scale;
        u[N + k] = s->target_b[k] / sc->amp_scale;
    }
    u[2 * N] = s->omega_rad_s / sc->omega_scale;
    return 2 * N + 1;
}

static double dist(const double *a, const double *b, int m) {
    double s = 0;
    for (int i = 0; i < m; i++)
        s += (a[i] - b[i]) * (a[i] - b[i]);
    return sqrt(s);
}

/* Model predictor of a natural sweep. Near a resonance the solution races but the residual map
 * does not: Phi(u, w) = J(w) u - f(w) with J and f smooth in w; J passes close to zero at the
 * resonance, and that is what makes u = J^-1 f peak (the carried Jacobian of a Q = 140 mode changes
 * by its own size between points 0.05 Hz apart, while J itself is nearly linear in w). J, the
 * response Jacobian R, and f = J u - Phi of the last few points (up to MODEL_POINTS), fitted by a
 * least-squares line in w (which averages the secant updates' noise) and evaluated at the new w,
 * predict the targets; J and R seed the corrector. Returns 0 with target_a/b filled and J, R
 * written into *corr, or -1 (the caller keeps the secant). */
enum { MODEL_POINTS = 4 };
static int model_predict(const rths_point *pts, int n_pts, double omega, int harmonics,
                         double *target_a, double *target_b, rths_corrector_state *corr) {
    enum { L = RTHS_MAX_UNKNOWNS };
    int n = 2 * harmonics, K = 0;
    const rths_point *p[MODEL_POINTS];
    for (int q = n_pts - 1; q >= 0 && K < MODEL_POINTS; q--) {
        if (!pts[q].corrector.have_jacobian || pts[q].sol.harmonics != harmonics) break;
        p[K++] = &pts[q];
    }
    if (K < 2) return -1;
    /* weights of the fitted line's value at omega: w_q = 1/K + (x - xbar)(x_q - xbar) / Sxx */
    double xbar = 0, sxx = 0, weight[MODEL_POINTS];
    for (int q = 0; q < K; q++)
        xbar += p[q]->sol.omega_rad_s / K;
    for (int q = 0; q < K; q++)
        sxx += (p[q]->sol.omega_rad_s - xbar) * (p[q]->sol.omega_rad_s - xbar);
    if (!(sxx > 0)) return -1;
    for (int q = 0; q < K; q++)
        weight[q] = 1.0 / K + (omega - xbar) * (p[q]->sol.omega_rad_s - xbar) / sxx;
    double jp[L * L] = {0}, rp[L * L] = {0}, fp[L] = {0}, u1[L];
    for (int q = 0; q < K; q++) {
        double u[L], phi[L];
        for (int k = 0; k < harmonics; k++) {
            u[k] = p[q]->sol.target_a[k];
            u[harmonics + k] = p[q]->sol.target_b[k];
        }
        if (q == 0) memcpy(u1, u, sizeof u);
        rths_evaluation_residual(&p[q]->sol.eval, phi, NULL);
        const double *J = p[q]->corrector.jacobian, *R = p[q]->corrector.response_jacobian;
        for (int i = 0; i < n; i++) {
            double f = -phi[i];
            for (int j = 0; j < n; j++) {
                f += J[i + j * L] * u[j];
                jp[i + j * L] += weight[q] * J[i + j * L];
                rp[i + j * L] += weight[q] * R[i + j * L];
            }
            fp[i] += weight[q] * f;
        }
    }
    double a[L * L], x[L];
    for (int i = 0; i < n; i++) {
        x[i] = fp[i];
        for (int j = 0; j < n; j++)
            a[i + j * n] = jp[i + j * L];
    }
    if (rths_mat_solve(n, 1, a, x) != 0) return -1;
    /* a wild prediction (a stale Jacobian at a point) is worse than the secant: keep the move
     * within twice the current target's size */
    double move = 0, size = 0;
    for (int i = 0; i < n; i++) {
        if (!isfinite(x[i])) return -1;
        move += (x[i] - u1[i]) * (x[i] - u1[i]);
        size += u1[i] * u1[i];
    }
    if (move > 4 * size) return -1;
    for (int k = 0; k < harmonics; k++) {
        target_a[k] = x[k];
        target_b[k] = x[harmonics + k];
    }
    if (corr->have_jacobian && corr->harmonics == harmonics)
        rths_corrector_seed_jacobians(corr, jp, rp);
    return 0;
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

int rths_continuation_run(rths_rig *rig, const rths_continuation_options *opt,
                          const rths_settle_options *settle, const rths_newton_options *newton,
                          int harmonics, double amplitude_n, const rths_point *resume, int n_resume,
                          rths_point_fn on_point, rths_progress_fn on_progress, void *user,
                          rths_continuation_result *res, rths_error *err) {
    memset(res, 0, sizeof *res);
    int cap = opt->max_points + 1;
    rths_point *pts = calloc((size_t)cap, sizeof *pts);
    double *svals = calloc((size_t)cap, sizeof *svals); /* cumulative scaled arclength */
    if (!pts || !svals) {
        free(pts), free(svals);
        return rths_error_set(err, RTHS_EFAIL, "out of memory for %d continuation points", cap);
    }
    double dir = opt->end_hz >= opt->start_hz ? 1.0 : -1.0;
    scaling sc = {.opt = opt,
                  .amp_scale = opt->amplitude_scale_m,
                  .harmonics = harmonics,
                  .omega_scale = 2 * M_PI * fmax(fabs(opt->end_hz - opt->start_hz), 1e-3)};
    rths_corrector_state corr;
    memset(&corr, 0, sizeof corr);
    int n = 0, segment = 0, consecutive = 0, status = RTHS_OK, wdir = 0, ext_idx = 0;
    double ds = opt->grow, step_hz = opt->initial_step_hz;
    /* a failed first point is retried from the corrector's last iterate (there is no step to
     * shrink): the cold start from a zero target may simply need more iterations */
    double first_a[RTHS_MAX_HARMONICS] = {0}, first_b[RTHS_MAX_HARMONICS] = {0};
    for (int i = 0; i < n_resume && i < cap; i++) {
        pts[n] = resume[i];
        if (n > 0) {
            double u0[RTHS_MAX_UNKNOWNS], u1[RTHS_MAX_UNKNOWNS];
            if (sc.amp_scale <= 0) sc.amp_scale = fmax(rths_point_amplitude_m(&pts[0]), 1e-9);
            int m = pack_point(&sc, &pts[n - 1].sol, u0);
            pack_point(&sc, &pts[n].sol, u1);
            svals[n] = svals[n - 1] + dist(u0, u1, m);
        }
        if (pts[n].fold)
            res->folds[res->n_folds < 32 ? res->n_folds++ : 31] = (rths_fold){
                pts[n].sol.omega_rad_s / (2 * M_PI), rths_point_amplitude_m(&pts[n]), n};
        res->evaluations += pts[n].evaluations;
        res->rig_time_s += pts[n].rig_time_s;
        segment = pts[n].segment;
        n++;
    }
    if (n >= 2) { /* rebuild the fold tracker from the resumed branch */
        wdir = pts[1].sol.omega_rad_s >= pts[0].sol.omega_rad_s ? 1 : -1;
        int start = 1;
        for (int f = 0; f < res->n_folds; f++) {
            wdir = -wdir;
            start = res->folds[f].after_point + 1;
        }
        ext_idx = start < n ? start : n - 1;
        for (int q = start; q < n; q++)
            if (wdir * (pts[q].sol.omega_rad_s - pts[ext_idx].sol.omega_rad_s) > 0) ext_idx = q;
    }
    if (n > 0) {
        corr = pts[n - 1].corrector;
        if (n >= 2 && opt->method == RTHS_CONT_NATURAL)
            step_hz = fabs(pts[n - 1].sol.omega_rad_s - pts[n - 2].sol.omega_rad_s) / (2 * M_PI);
        if (dir * (pts[n - 1].sol.omega_rad_s / (2 * M_PI) - opt->end_hz) >= 0) {
            res->reached_end = 1;
            snprintf(res->stop_reason, sizeof res->stop_reason,
                     "end frequency %.6g Hz already reached", opt->end_hz);
        }
    }
    res->points = n;
    res->converged_points = n;

    while (!res->reached_end && n < opt->max_points) {
        rths_solution sol;
        memset(&sol, 0, sizeof sol);
        sol.harmonics = harmonics;
        rths_arclength arc;
        memset(&arc, 0, sizeof arc);
        arc.amplitude_scale_m = sc.amp_scale > 0 ? sc.amp_scale : 1e-4;
        arc.omega_scale_rad_s = sc.omega_scale;
        double step_used = 0;
        if (n == 0) {
            sol.omega_rad_s = 2 * M_PI * opt->start_hz; /* zero target as the first guess */
            memcpy(sol.target_a, first_a, sizeof first_a);
            memcpy(sol.target_b, first_b, sizeof first_b);
        } else if (n == 1 || opt->method == RTHS_CONT_NATURAL) {
            const rths_solution *p1 = &pts[n - 1].sol;
            double f = p1->omega_rad_s / (2 * M_PI) + dir * step_hz;
            if (dir * (f - opt->end_hz) > 0) f = opt->end_hz;
            sol.omega_rad_s = 2 * M_PI * f;
            for (int k = 0; k < harmonics; k++) {
                sol.target_a[k] = p1->target_a[k];
                sol.target_b[k] = p1->target_b[k];
            }
            if (n >= 2 && opt->model_predictor &&
                (rths_corrector_lti_predict(&corr, harmonics, sol.omega_rad_s, sol.target_a,
                                            sol.target_b) == 0 ||
                 model_predict(pts, n, sol.omega_rad_s, harmonics, sol.target_a, sol.target_b,
                               &corr) == 0)) {
                /* targets and Jacobians predicted from the residual model */
            } else if (n >= 2) { /* secant extrapolation of the targets in frequency */
                const rths_solution *p0 = &pts[n - 2].sol;
                double t =
                    (sol.omega_rad_s - p1->omega_rad_s) / (p1->omega_rad_s - p0->omega_rad_s);
                for (int k = 0; k < harmonics; k++) {
                    sol.target_a[k] += t * (p1->target_a[k] - p0->target_a[k]);
                    sol.target_b[k] += t * (p1->target_b[k] - p0->target_b[k]);
                }
            }
            step_used = fabs(f - p1->omega_rad_s / (2 * M_PI));
        } else {
            double u0[RTHS_MAX_UNKNOWNS], u1[RTHS_MAX_UNKNOWNS], sec[RTHS_MAX_UNKNOWNS];
            int m = pack_point(&sc, &pts[n - 2].sol, u0);
            pack_point(&sc, &pts[n - 1].sol, u1);
            double len = 0;
            for (int i = 0; i < m; i++) {
                sec[i] = u1[i] - u0[i];
                len += sec[i] * sec[i];
            }
            len = sqrt(len);
            double want = rths_clamp(ds * len, opt->min_step, opt->max_step);
            double mult = len > 0 ? want / len : 0;
            arc.active = 1;
            for (int i = 0; i < m; i++) {
                arc.tangent[i] = sec[i] / len;
                arc.predicted[i] = u1[i] + mult * sec[i]; /* erratum 4: u_-1 + ds * secant */
            }
            for (int k = 0; k < harmonics; k++) {
                sol.target_a[k] = arc.predicted[k] * sc.amp_scale;
                sol.target_b[k] = arc.predicted[harmonics + k] * sc.amp_scale;
            }
            sol.omega_rad_s = arc.predicted[m - 1] * sc.omega_scale;
            step_used = want;
        }
        int rc = rths_correct(rig, settle, newton, amplitude_n, &arc, &corr, &sol, err);
        res->evaluations += corr.evaluations;
        res->rig_time_s += corr.rig_time_s;
        if (on_progress)
            on_progress(user, n, sol.omega_rad_s / (2 * M_PI), sol.residual_norm_m,
                        res->evaluations, rc == RTHS_OK);
        if (rc != RTHS_OK) {
            if (rths_rig_get_fault(rig) != RTHS_RIG_OK || !isfinite(sol.residual_norm_m)) {
                status = RTHS_EFAIL;
                snprintf(res->stop_reason, sizeof res->stop_reason, "%s", err->msg);
                break;
            }
            res->failures++;
            consecutive++;
            /* a failed attempt's rig time is charged to the next accepted point */
            pts[n].rig_time_s += corr.rig_time_s;
            pts[n].evaluations += corr.evaluations;
            if (consecutive > opt->max_failures) {
                snprintf(res->stop_reason, sizeof res->stop_reason,
                         "stopped after %d failed corrections in a row near %.6g Hz: %s",
                         consecutive, sol.omega_rad_s / (2 * M_PI), err->msg);
                break;
            }
            /* a carried Jacobian that misled the corrector is dropped, so the retry starts fresh */
            corr.have_jacobian = 0;
            if (n == 0) {
                for (int k = 0; k < harmonics; k++)
                    if (isfinite(sol.target_a[k]) && isfinite(sol.target_b[k])) {
                        first_a[k] = sol.target_a[k];
                        first_b[k] = sol.target_b[k];
                    }
                continue;
            }
            if (n == 1 || opt->method == RTHS_CONT_NATURAL)
                step_hz *= opt->shrink;
            else
                ds *= opt->shrink;
            if (opt->method == RTHS_CONT_ARCLENGTH && n >= 2 && step_used <= opt->min_step) {
                snprintf(res->stop_reason, sizeof res->stop_reason,
                         "step fell below the minimum %.3g near %.6g Hz", opt->min_step,
                         sol.omega_rad_s / (2 * M_PI));
                break;
            }
            continue;
        }
        consecutive = 0;
        if (n == 0 && sc.amp_scale <= 0) {
            /* scaling fixed from the first solution; only the frequency column depends on it */
            double amp = fmax(hypot(sol.target_a[0], sol.target_b[0]), 1e-9);
            for (int i = 0; i < 2 * harmonics; i++) {
                corr.jacobian[i + 2 * harmonics * RTHS_MAX_UNKNOWNS] *= arc.amplitude_scale_m / amp;
                corr.response_jacobian[i + 2 * harmonics * RTHS_MAX_UNKNOWNS] *=
                    arc.amplitude_scale_m / amp;
            }
            sc.amp_scale = amp;
        }
        rths_point *pt = &pts[n];
        pt->index = n;
        pt->sol = sol;
        pt->evaluations += corr.evaluations;
        pt->iterations = corr.iterations;
        pt->rig_time_s += corr.rig_time_s;
        pt->step = step_used;
        pt->segment = segment;
        pt->corrector = corr;
        if (n > 0) {
            double u0[RTHS_MAX_UNKNOWNS], u1[RTHS_MAX_UNKNOWNS];
            int m = pack_point(&sc, &pts[n - 1].sol, u0);
            pack_point(&sc, &sol, u1);
            svals[n] = svals[n - 1] + dist(u0, u1, m);
            pt->secant_omega = sol.omega_rad_s - pts[n - 1].sol.omega_rad_s;
        }
        /* Fold: the frequency along the branch turns back. Correction error makes the frequency
         * jitter where the branch is vertical, so a turn counts only once the frequency has moved
         * back from its extreme by a margin (5 % of the step); the fold is then located on the
         * parabola through the extreme point and its neighbours. */
        if (n == 1) {
            wdir = pt->secant_omega >= 0 ? 1 : -1;
            ext_idx = 1;
        } else if (n >= 2) {
            double w = sol.omega_rad_s / sc.omega_scale;
            double w_ext = pts[ext_idx].sol.omega_rad_s / sc.omega_scale;
            double margin = 0.05 * fmax(step_used, opt->min_step);
            if (wdir * (w - w_ext) > 0) {
                ext_idx = n;
            } else if (wdir * (w_ext - w) > margin && ext_idx >= 1 && ext_idx < n) {
                int e = ext_idx;
                double s3[3] = {svals[e - 1], svals[e], svals[e + 1]};
                double w3[3] = {pts[e - 1].sol.omega_rad_s, pts[e].sol.omega_rad_s,
                                pts[e + 1].sol.omega_rad_s};
                double a3[3] = {rths_point_amplitude_m(&pts[e - 1]),
                                rths_point_amplitude_m(&pts[e]),
                                rths_point_amplitude_m(&pts[e + 1])};
                double s_star = s3[1];
                if (!parabola_vertex(s3, w3, &s_star)) s_star = s3[1];
                double w_star = 0, a_star = 0; /* Lagrange interpolation at s_star */
                for (int i = 0; i < 3; i++) {
                    double l = 1;
                    for (int j = 0; j < 3; j++)
                        if (j != i) l *= (s_star - s3[j]) / (s3[i] - s3[j]);
                    w_star += l * w3[i];
                    a_star += l * a3[i];
                }
                int after = s_star < s3[1] ? e - 1 : e;
                pts[after].fold = 1;
                segment++;
                for (int q = after + 1; q <= n; q++)
                    pts[q].segment = segment;
                if (res->n_folds < 32)
                    res->folds[res->n_folds++] = (rths_fold){w_star / (2 * M_PI), a_star, after};
                if (on_point)
                    for (int q = after; q < n && status == RTHS_OK; q++)
                        status = on_point(user, &pts[q], 1);
                wdir = -wdir;
                ext_idx = n;
                for (int q = e + 1; q <= n; q++)
                    if (wdir * (pts[q].sol.omega_rad_s - pts[ext_idx].sol.omega_rad_s) > 0)
                        ext_idx = q;
            }
        }
        n++;
        res->points = n;
        res->converged_points = n;
        if (status == RTHS_OK && on_point) status = on_point(user, pt, 0);
        if (status != RTHS_OK) {
            snprintf(res->stop_reason, sizeof res->stop_reason, "stopped by the point handler");
            break;
        }
        if (n >= 2 && opt->method == RTHS_CONT_ARCLENGTH)
            ds = opt->grow;
        else if (n >= 2)
            step_hz = fmin(step_hz * opt->grow, opt->max_step_hz);
        if (dir * (sol.omega_rad_s / (2 * M_PI) - opt->end_hz) >= -1e-12) {
            res->reached_end = 1;
            snprintf(res->stop_reason, sizeof res->stop_reason, "reached the end frequency %.6g Hz",
                     opt->end_hz);
        }
    }
    if (!res->reached_end && !res->stop_reason[0])
        snprintf(res->stop_reason, sizeof res->stop_reason, "reached the point limit (%d)",
                 opt->max_points);
    free(pts);
    free(svals);
    return status;
}
