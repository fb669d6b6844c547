/* Predictors of the next continuation point: the seed's secant (natural or pseudo-arclength,
 * erratum 4) and, on a natural sweep, the residual model. */
#include "continuation/continuation_internal.h"

#include <math.h>
#include <string.h>

int cont_pack(const cont_scaling *sc, const rths_solution *s, double *u) {
    int N = sc->harmonics;
    for (int k = 0; k < N; k++) {
        u[k] = s->target_a[k] / sc->amp_scale;
        u[N + k] = s->target_b[k] / sc->amp_scale;
    }
    u[2 * N] = s->omega_rad_s / sc->omega_scale;
    return 2 * N + 1;
}

static void targets_of(const rths_solution *s, double *u) {
    int N = s->harmonics;
    for (int k = 0; k < N; k++) {
        u[k] = s->target_a[k];
        u[N + k] = s->target_b[k];
    }
}

/* Model predictor of a natural sweep. Near a resonance the solution races but the residual map
 * does not: Phi(u, w) = J(w) u - f(w) with J and f smooth in w; J passes close to zero at the
 * resonance, and that is what makes u = J^-1 f peak (the carried Jacobian of a Q = 140 mode
 * changes by its own size between points 0.05 Hz apart, while J itself is nearly linear in w). J,
 * the response Jacobian R, and f = J u - Phi of the last few points (up to MODEL_POINTS), fitted
 * by a least-squares line in w (which averages the secant updates' noise) and evaluated at the new
 * w, predict the targets; J and R seed the corrector. Returns 0 with u filled, -2 when the
 * prediction lies outside the targets' trust region, or -1 (the caller keeps the secant). */
enum { MODEL_POINTS = 4 };

/* Weights of the fitted line's value at omega, w_q = 1/K + (x - xbar)(x_q - xbar) / Sxx; 0, or
 * -1 if the points share one frequency. */
static int line_weights(const rths_point *const *p, int K, double omega, double *weight) {
    double xbar = 0, sxx = 0;
    for (int q = 0; q < K; q++)
        xbar += p[q]->sol.omega_rad_s / K;
    for (int q = 0; q < K; q++)
        sxx += (p[q]->sol.omega_rad_s - xbar) * (p[q]->sol.omega_rad_s - xbar);
    if (!(sxx > 0)) return -1;
    for (int q = 0; q < K; q++)
        weight[q] = 1.0 / K + (omega - xbar) * (p[q]->sol.omega_rad_s - xbar) / sxx;
    return 0;
}

/* The weighted J, R and f = J u - Phi of the points. */
static void weighted_model(const rths_point *const *p, int K, const double *weight, int n,
                           double *jp, double *rp, double *fp) {
    enum { L = CONT_LD };
    for (int q = 0; q < K; q++) {
        double u[L], J[L * L], R[L * L];
        targets_of(&p[q]->sol, u);
        rths_corrector_saved_jacobians(&p[q]->corrector, J, R);
        const double *phi = p[q]->residual.phi;
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
}

static int model_predict(cont_run *run, double omega, double *u_out) {
    enum { L = CONT_LD };
    int n = 2 * run->harmonics, K = 0;
    const rths_point *p[MODEL_POINTS];
    double scratch[L * L];
    for (int q = run->n - 1; q >= 0 && K < MODEL_POINTS; q--) {
        if (!rths_corrector_saved_jacobians(&run->pts[q].corrector, scratch, scratch) ||
            run->pts[q].sol.harmonics != run->harmonics)
            break;
        p[K++] = &run->pts[q];
    }
    double weight[MODEL_POINTS];
    if (K < 2 || line_weights(p, K, omega, weight)) return -1;
    double jp[L * L] = {0}, rp[L * L] = {0}, fp[L] = {0}, u1[L], a[L * L], x[L];
    weighted_model(p, K, weight, n, jp, rp, fp);
    targets_of(&p[0]->sol, u1);
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
    if (!rths_corrector_trust_allows(run->corr, x)) return -2;
    memcpy(u_out, x, sizeof(double) * (size_t)n);
    rths_corrector_seed_jacobians(run->corr, jp, rp);
    return 0;
}

/* The target predictors of a natural step, tried in order: each returns 0 with u (holding the last
 * point's targets on entry) filled, or -1 to pass to the next (-2: its prediction lay outside the
 * targets' trust region). The residual-model ones also seed the corrector's Jacobians. */
typedef int (*cont_target_predictor)(cont_run *run, double omega, double *u);

/* The LTI rig's per-harmonic gains fitted to the corrector's evaluation history. */
static int predict_lti(cont_run *run, double omega, double *u) {
    return run->opt->model_predictor ? rths_corrector_lti_predict(run->corr, omega, u) : -1;
}

/* Lines in w through the last points' Jacobians and f = J u - Phi (model_predict). */
static int predict_residual_model(cont_run *run, double omega, double *u) {
    return run->opt->model_predictor ? model_predict(run, omega, u) : -1;
}

/* Size of point q's targets, or of its measured physical response if larger, in metres. */
static double point_size(const cont_run *run, int q) {
    const rths_point *p = &run->pts[q];
    int n = 2 * run->harmonics;
    double u[CONT_LD], target = 0, response = 0;
    targets_of(&p->sol, u);
    for (int i = 0; i < n; i++) {
        target += u[i] * u[i];
        response += p->residual.response[i] * p->residual.response[i];
    }
    return sqrt(fmax(target, response));
}

/* The trust region's anchor (docs/method.md, "Iteration and continuation"): the last accepted
 * point's size, times its growth from the point before when it grew (on the flank of a resonance
 * the size may keep growing at the rate it just did). */
static double trust_anchor(const cont_run *run) {
    double last = point_size(run, run->n - 1);
    if (run->n < 2) return last;
    double before = point_size(run, run->n - 2);
    return before > 0 && last > before ? last * last / before : last;
}

/* The seed's secant: the targets extrapolated linearly in frequency from the last two points. */
static int predict_secant(cont_run *run, double omega, double *u) {
    int n = run->n, N = run->harmonics;
    const rths_solution *p1 = &run->pts[n - 1].sol, *p0 = &run->pts[n - 2].sol;
    double t = (omega - p1->omega_rad_s) / (p1->omega_rad_s - p0->omega_rad_s);
    for (int k = 0; k < N; k++) {
        u[k] += t * (p1->target_a[k] - p0->target_a[k]);
        u[N + k] += t * (p1->target_b[k] - p0->target_b[k]);
    }
    return 0;
}

static const cont_target_predictor natural_predictors[] = {predict_lti, predict_residual_model,
                                                           predict_secant};

/* Natural parameter (and the first step of an arclength run): the next frequency, the targets
 * from the first predictor that answers (from the second point on; the first step keeps the
 * last targets). */
static void predict_natural(cont_run *run, cont_prediction *pr) {
    const rths_continuation_options *opt = run->opt;
    const rths_solution *p1 = &run->pts[run->n - 1].sol;
    double f = p1->omega_rad_s / (2 * M_PI) + run->dir * run->step_hz;
    if (run->dir * (f - opt->end_hz) > 0) f = opt->end_hz;
    pr->omega_rad_s = 2 * M_PI * f;
    targets_of(p1, pr->u);
    int count = (int)(sizeof natural_predictors / sizeof natural_predictors[0]);
    for (int i = 0; run->n >= 2 && i < count; i++) {
        int rc = natural_predictors[i](run, pr->omega_rad_s, pr->u);
        if (rc == 0) break;
        pr->trust_declined += rc == -2;
    }
    pr->step_used = fabs(f - p1->omega_rad_s / (2 * M_PI));
}

/* The quadratic pseudo-arclength predictor (iteration.quadratic_predictor; docs/method.md, "The
 * fitted evaluation"): the quadratic through the last three points, parametrised by their chord
 * lengths, evaluated at the step `want` beyond the last; the secant's error is second order in
 * the step, this one's third. The arclength row keeps the secant's direction. */
static int quadratic_wanted(const cont_run *run) {
    return rths_corrector_quadratic_predictor(run->corr);
}

static void quadratic_prediction(const cont_run *run, const double *u1, const double *u2, double l2,
                                 double want, double *predicted) {
    double um[CONT_LD];
    int m = cont_pack(&run->sc, &run->pts[run->n - 3].sol, um);
    double l1 = 0;
    for (int i = 0; i < m; i++)
        l1 += (u1[i] - um[i]) * (u1[i] - um[i]);
    l1 = sqrt(l1);
    if (!(l1 > 0 && l2 > 0)) return;
    double s = want;
    double w2 = (s + l2) * (s + l1 + l2) / (l2 * (l1 + l2));
    double w1 = -s * (s + l1 + l2) / (l2 * l1);
    double w0 = s * (s + l2) / (l1 * (l1 + l2));
    for (int i = 0; i < m; i++)
        predicted[i] = w2 * u2[i] + w1 * u1[i] + w0 * um[i];
}

/* Pseudo-arclength: u_pred = u_-1 + ds * (u_-1 - u_-2) in scaled variables (erratum 4), the step
 * clamped to [min_step, max_step], with the arclength row along the secant. */
static void predict_arclength(cont_run *run, cont_prediction *pr) {
    const rths_continuation_options *opt = run->opt;
    const cont_scaling *sc = &run->sc;
    int n = run->n, N = run->harmonics;
    double u0[CONT_LD], u1[CONT_LD], sec[CONT_LD], len = 0;
    int m = cont_pack(sc, &run->pts[n - 2].sol, u0);
    cont_pack(sc, &run->pts[n - 1].sol, u1);
    for (int i = 0; i < m; i++) {
        sec[i] = u1[i] - u0[i];
        len += sec[i] * sec[i];
    }
    len = sqrt(len);
    double want = rths_clamp(run->ds * len, opt->min_step, opt->max_step);
    double mult = len > 0 ? want / len : 0;
    pr->arc.active = 1;
    for (int i = 0; i < m; i++) {
        pr->arc.tangent[i] = sec[i] / len;
        pr->arc.predicted[i] = u1[i] + mult * sec[i];
    }
    if (n >= 3 && quadratic_wanted(run))
        quadratic_prediction(run, u0, u1, len, want, pr->arc.predicted);
    for (int k = 0; k < N; k++) {
        pr->u[k] = pr->arc.predicted[k] * sc->amp_scale;
        pr->u[N + k] = pr->arc.predicted[N + k] * sc->amp_scale;
    }
    pr->omega_rad_s = pr->arc.predicted[m - 1] * sc->omega_scale;
    pr->step_used = want;
}

void cont_predict(cont_run *run, cont_prediction *pr) {
    memset(pr, 0, sizeof *pr);
    rths_corrector_set_trust_anchor(run->corr, run->n > 0 ? trust_anchor(run) : 0);
    pr->arc.amplitude_scale_m = run->sc.amp_scale > 0 ? run->sc.amp_scale : 1e-4;
    pr->arc.omega_scale_rad_s = run->sc.omega_scale;
    if (run->n == 0) { /* the first point: zero target (or the failed attempt's last iterate) */
        pr->omega_rad_s = 2 * M_PI * run->opt->start_hz;
        memcpy(pr->u, run->first_u, sizeof pr->u);
    } else if (run->n == 1 || run->opt->method == RTHS_CONT_NATURAL || run->natural_next) {
        predict_natural(run, pr);
        pr->natural_fallback = run->n >= 2 && run->opt->method == RTHS_CONT_ARCLENGTH;
    } else {
        predict_arclength(run, pr);
        /* a branch without folds ends exactly at end_hz: a step that would cross it becomes a
         * natural step onto it (the arclength step cannot aim at a frequency) */
        const rths_continuation_options *opt = run->opt;
        if (opt->monotonic && run->dir * (pr->omega_rad_s / (2 * M_PI) - opt->end_hz) > 0) {
            double last_hz = run->pts[run->n - 1].sol.omega_rad_s / (2 * M_PI);
            memset(pr, 0, sizeof *pr);
            pr->arc.amplitude_scale_m = run->sc.amp_scale;
            pr->arc.omega_scale_rad_s = run->sc.omega_scale;
            /* after a failed attempt the step shrunk (step_shrink): keep it */
            if (run->consecutive == 0) run->step_hz = fabs(opt->end_hz - last_hz);
            predict_natural(run, pr);
            pr->natural_fallback = 1;
        }
    }
}
