/* Natural and pseudo-arclength continuation in forcing frequency: the driver. Each step predicts
 * (predict.c), corrects (the corrector object), and on success accepts the point, tracks folds
 * (fold.c) and grows the step; on failure shrinks it (step control below). */
#include "continuation/continuation_internal.h"

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
    opt->range_margin = 0.05;
    opt->monotonic = 0;
}

int rths_point_stable(const rths_point *pt) {
    return pt->segment % 2 == 0;
}

double rths_point_amplitude_m(const rths_point *pt) {
    return hypot(pt->sol.eval.phys.a[1], pt->sol.eval.phys.b[1]);
}

/* ---- step control ---- */

/* After an accepted point (n points now): the seed's policy, ds back to grow (u_-1 + 1.1 secant)
 * on an arclength run, the frequency step grown by grow up to max_step_hz on a natural one. */
static void step_grow(cont_run *run) {
    const rths_continuation_options *opt = run->opt;
    if (run->n >= 2 && opt->method == RTHS_CONT_ARCLENGTH)
        run->ds = opt->grow;
    else if (run->n >= 2)
        run->step_hz = fmin(run->step_hz * opt->grow, opt->max_step_hz);
}

/* After a failed correction: x shrink and retry. Returns 0, or -1 when the arclength step fell
 * below its minimum (the run ends). */
static int step_shrink(cont_run *run, const cont_prediction *pr) {
    const rths_continuation_options *opt = run->opt;
    if (run->n == 1 || opt->method == RTHS_CONT_NATURAL || pr->natural_fallback)
        run->step_hz *= opt->shrink;
    else
        run->ds *= opt->shrink;
    if (opt->method == RTHS_CONT_ARCLENGTH && run->n >= 2 && !pr->natural_fallback &&
        pr->step_used <= opt->min_step)
        return -1;
    return 0;
}

/* ---- the run ---- */

static int run_init(cont_run *run, const rths_continuation_options *opt, int harmonics,
                    rths_continuation_result *res, rths_error *err) {
    memset(res, 0, sizeof *res);
    run->opt = opt;
    run->harmonics = harmonics;
    run->res = res;
    run->cap = opt->max_points + 1;
    run->pts = calloc((size_t)run->cap, sizeof *run->pts);
    run->folds.svals = calloc((size_t)run->cap, sizeof *run->folds.svals);
    if (!run->pts || !run->folds.svals)
        return rths_error_set(err, RTHS_EFAIL, "out of memory for %d continuation points",
                              run->cap);
    run->dir = opt->end_hz >= opt->start_hz ? 1.0 : -1.0;
    run->sc =
        (cont_scaling){.amp_scale = opt->amplitude_scale_m,
                       .harmonics = harmonics,
                       .omega_scale = 2 * M_PI * fmax(fabs(opt->end_hz - opt->start_hz), 1e-3)};
    run->ds = opt->grow;
    run->step_hz = opt->initial_step_hz;
    return RTHS_OK;
}

/* The amplitude scale, fixed from the first solution's target amplitude. */
static double first_amplitude_scale(const rths_solution *s) {
    return fmax(hypot(s->target_a[0], s->target_b[0]), 1e-9);
}

/* Pseudo-arclength measures the branch in targets / amplitude scale and omega / omega scale. A
 * scale fixed at the first point (far from resonance, tiny) makes every step near a resonance
 * almost all amplitude: a 3-25 Hz sweep at 0.25 N crawled to 4.3 Hz in 500 points. The scale
 * for the correction of point k is therefore the target amplitude of point k - 1 (the first
 * point's for k <= 1, and never below 1e-3 of it): a step then weighs relative amplitude (and
 * phase) against frequency, as log-amplitude scaling would. An explicit
 * continuation.amplitude_scale_m keeps its fixed scale. */
static double running_scale(const cont_run *run, int k) {
    const rths_continuation_options *opt = run->opt;
    if (opt->amplitude_scale_m > 0) return opt->amplitude_scale_m;
    double first = first_amplitude_scale(&run->pts[0].sol);
    if (opt->method != RTHS_CONT_ARCLENGTH || k <= 1) return first;
    return fmax(first_amplitude_scale(&run->pts[k - 1].sol), 1e-3 * first);
}

/* Before correcting point n: the scale follows the branch (running_scale), and the carried
 * Jacobians' frequency columns with it. */
static void follow_amplitude_scale(cont_run *run) {
    if (run->n < 1) return;
    double scale = running_scale(run, run->n);
    if (scale == run->sc.amp_scale) return;
    rths_corrector_rescale_amplitude(run->corr, run->sc.amp_scale, scale);
    run->sc.amp_scale = scale;
}

/* Replays a journal's points: counts, arclength and folds as the interrupted run had them, and
 * the corrector state of the last one. */
static int run_resume(cont_run *run, const rths_point *resume, int n_resume, rths_error *err) {
    rths_continuation_result *res = run->res;
    for (int i = 0; i < n_resume && i < run->cap; i++) {
        int n = run->n;
        run->pts[n] = resume[i];
        /* the scale point n's correction used (follow_amplitude_scale), so the fold tracker
         * measures the same arclength as the uninterrupted run did */
        if (n >= 1 || run->sc.amp_scale <= 0) run->sc.amp_scale = running_scale(run, n);
        cont_fold_track(run, n, 0);
        res->evaluations += run->pts[n].evaluations;
        res->rig_time_s += run->pts[n].rig_time_s;
        run->n++;
    }
    int n = run->n;
    res->points = res->converged_points = n;
    if (n == 0) return RTHS_OK;
    /* every point from here on is measured by a rig that started again from rest, with its own
     * noise stream: marked (docs/journal.md, "What a resume restores") */
    run->resumed_run = 1;
    int rc = rths_corrector_load(run->corr, &run->pts[n - 1].corrector, err);
    if (rc) return rc;
    /* the state saved with point n - 1 is in the scale its correction used */
    run->sc.amp_scale = running_scale(run, n - 1);
    /* the step that reached point n - 1, grown after that success as step_grow did */
    if (n >= 2 && run->opt->method == RTHS_CONT_NATURAL)
        run->step_hz =
            fmin(fabs(run->pts[n - 1].sol.omega_rad_s - run->pts[n - 2].sol.omega_rad_s) /
                     (2 * M_PI) * run->opt->grow,
                 run->opt->max_step_hz);
    if (run->dir * (run->pts[n - 1].sol.omega_rad_s / (2 * M_PI) - run->opt->end_hz) >= 0) {
        res->reached_end = 1;
        snprintf(res->stop_reason, sizeof res->stop_reason, "end frequency %.6g Hz already reached",
                 run->opt->end_hz);
    }
    return RTHS_OK;
}

/* ---- why corrections fail ---- */

/* A failure's kind: its message with every number replaced by '#', so "target of up to 0.01043 m
 * is beyond the displacement limit" and "... 0.01042 m ..." count as one cause. */
static void failure_kind(const char *msg, char *kind, size_t cap) {
    size_t n = 0;
    for (const char *p = msg; *p && n + 1 < cap;) {
        int starts_number =
            (*p >= '0' && *p <= '9') || ((*p == '-' || *p == '.') && p[1] >= '0' && p[1] <= '9');
        if (!starts_number) {
            kind[n++] = *p++;
            continue;
        }
        kind[n++] = '#';
        p++;
        while ((*p >= '0' && *p <= '9') || *p == '.' ||
               ((*p == 'e' || *p == 'E') &&
                (p[1] == '-' || p[1] == '+' || (p[1] >= '0' && p[1] <= '9'))) ||
               ((*p == '-' || *p == '+') && (p[-1] == 'e' || p[-1] == 'E')))
            p++;
    }
    kind[n] = 0;
}

static void remember_failure(cont_run *run, const char *msg) {
    cont_failure *f = &run->recent[run->n_recent_total++ % CONT_RECENT_FAILURES];
    snprintf(f->msg, sizeof f->msg, "%.*s", (int)sizeof f->msg - 1, msg);
}

/* The most frequent kind among the last CONT_RECENT_FAILURES failed corrections, as
 * "; the cause (K of the last M failed corrections): MESSAGE" with the latest message of that
 * kind, appended to the stop reason: a sweep that ends short of its end says what kept it from
 * going on (e.g. the target beyond the stroke limit), not only that its step shrank. */
static void append_cause(cont_run *run) {
    int m = run->n_recent_total < CONT_RECENT_FAILURES ? run->n_recent_total : CONT_RECENT_FAILURES;
    if (m == 0) return;
    static _Thread_local char kinds[CONT_RECENT_FAILURES][sizeof(((cont_failure *)0)->msg)];
    int best = -1, best_count = 0;
    for (int i = 0; i < m; i++) /* newest first, so a tie goes to the latest */
        failure_kind(run->recent[(run->n_recent_total - 1 - i) % CONT_RECENT_FAILURES].msg,
                     kinds[i], sizeof kinds[i]);
    for (int i = 0; i < m; i++) {
        int count = 0;
        for (int k = 0; k < m; k++)
            count += !strcmp(kinds[i], kinds[k]);
        if (count > best_count) best = i, best_count = count;
    }
    const char *msg = run->recent[(run->n_recent_total - 1 - best) % CONT_RECENT_FAILURES].msg;
    size_t len = strlen(run->res->stop_reason);
    snprintf(run->res->stop_reason + len, sizeof run->res->stop_reason - len,
             "; the cause (%d of the last %d failed corrections): %s", best_count, m, msg);
}

/* The caller's line on a failed correction: where, how many in a row, why, what follows. */
static void note_failure(const cont_run *run, double omega, const char *why, const char *next) {
    if (!run->opt->note) return;
    char line[1024];
    snprintf(line, sizeof line, "correction failed near %.6g Hz (%d in a row): %s; %s",
             omega / (2 * M_PI), run->consecutive, why, next);
    run->opt->note(run->opt->note_user, line);
}

/* A failed correction: charged to the next point, retried with a smaller step (the first point
 * from the corrector's last iterate). Returns 1 when the run must stop. */
static int on_failure(cont_run *run, const cont_prediction *pr, const rths_error *err) {
    rths_continuation_result *res = run->res;
    const rths_solution *sol = rths_corrector_solution(run->corr);
    int evals;
    double rig_time;
    rths_corrector_counters(run->corr, &evals, NULL, &rig_time);
    res->failures++;
    run->consecutive++;
    remember_failure(run, err->msg);
    run->pts[run->n].rig_time_s += rig_time;
    run->pts[run->n].evaluations += evals;
    if (run->consecutive > run->opt->max_failures) {
        snprintf(res->stop_reason, sizeof res->stop_reason,
                 "stopped after %d failed corrections in a row near %.6g Hz", run->consecutive,
                 sol->omega_rad_s / (2 * M_PI));
        append_cause(run);
        res->stopped_short = 1;
        note_failure(run, sol->omega_rad_s, err->msg, "the run stops");
        return 1;
    }
    /* a carried Jacobian that misled the corrector is dropped, so the retry starts fresh */
    rths_corrector_forget_jacobian(run->corr);
    if (run->n == 0) {
        note_failure(run, sol->omega_rad_s, err->msg,
                     "the first point is tried again from the corrector's last iterate, with a "
                     "fresh Jacobian");
        int N = run->harmonics;
        for (int k = 0; k < N; k++)
            if (isfinite(sol->target_a[k]) && isfinite(sol->target_b[k])) {
                run->first_u[k] = sol->target_a[k];
                run->first_u[N + k] = sol->target_b[k];
            }
        return 0;
    }
    if (step_shrink(run, pr)) {
        snprintf(res->stop_reason, sizeof res->stop_reason,
                 "step fell below the minimum %.3g near %.6g Hz", run->opt->min_step,
                 sol->omega_rad_s / (2 * M_PI));
        append_cause(run);
        res->stopped_short = 1;
        note_failure(run, sol->omega_rad_s, err->msg,
                     "the step fell below its minimum and the run stops");
        return 1;
    }
    note_failure(run, sol->omega_rad_s, err->msg,
                 "retried with a shorter step and a fresh Jacobian");
    return 0;
}

/* An accepted point: stored with its counters and corrector state, folds tracked, reported.
 * Returns the handler's status. */
static int on_accept(cont_run *run, const cont_prediction *pr) {
    const rths_solution *sol = rths_corrector_solution(run->corr);
    int n = run->n;
    run->consecutive = 0;
    run->natural_next = 0;
    if (n == 0 && run->sc.amp_scale <= 0) {
        /* scaling fixed from the first solution; only the frequency column depends on it */
        double amp = first_amplitude_scale(sol);
        rths_corrector_rescale_amplitude(run->corr, pr->arc.amplitude_scale_m, amp);
        run->sc.amp_scale = amp;
    }
    rths_point *pt = &run->pts[n];
    int evals, iters;
    double rig_time;
    rths_corrector_counters(run->corr, &evals, &iters, &rig_time);
    pt->index = n;
    pt->sol = *sol;
    pt->residual = *rths_corrector_residual(run->corr);
    pt->evaluations += evals;
    pt->iterations = iters;
    pt->rig_time_s += rig_time;
    pt->step = pr->step_used;
    pt->resumed = run->resumed_run;
    rths_corrector_save(run->corr, &pt->corrector);
    if (n > 0) pt->secant_omega = sol->omega_rad_s - run->pts[n - 1].sol.omega_rad_s;
    int status = cont_fold_track(run, n, 1);
    run->n++;
    run->res->points = run->res->converged_points = run->n;
    if (status == RTHS_OK && run->on_point) status = run->on_point(run->user, pt, 0);
    if (status != RTHS_OK) {
        snprintf(run->res->stop_reason, sizeof run->res->stop_reason,
                 "stopped by the point handler");
        return status;
    }
    step_grow(run);
    if (run->dir * (sol->omega_rad_s / (2 * M_PI) - run->opt->end_hz) >= -1e-12) {
        run->res->reached_end = 1;
        snprintf(run->res->stop_reason, sizeof run->res->stop_reason,
                 "reached the end frequency %.6g Hz", run->opt->end_hz);
    }
    return RTHS_OK;
}

enum { BOUND_OK, BOUND_RANGE, BOUND_MOVED_BACK, BOUND_PAST_END };

/* A converged point the branch may not take: outside the range (beyond start: *leave = 1, the
 * run ends), or moving back on a branch without folds. Returns BOUND_OK, or which bound with err
 * saying why. */
static int out_of_bounds(const cont_run *run, const rths_solution *sol, int *leave,
                         rths_error *err) {
    const rths_continuation_options *opt = run->opt;
    double f = sol->omega_rad_s / (2 * M_PI);
    double margin = opt->range_margin * fabs(opt->end_hz - opt->start_hz);
    *leave = 0;
    if (opt->range_margin > 0 && run->dir * (opt->start_hz - f) > margin) {
        *leave = 1;
        rths_error_set(err, RTHS_EFAIL,
                       "the branch left the requested range at %.6g Hz (start %.6g Hz)", f,
                       opt->start_hz);
        return BOUND_RANGE;
    }
    if (opt->range_margin > 0 && run->dir * (f - opt->end_hz) > margin) {
        rths_error_set(err, RTHS_EFAIL, "step overshot the end frequency to %.6g Hz", f);
        return BOUND_RANGE;
    }
    /* a branch without folds ends exactly at end_hz (predict.c): an arclength correction that
     * carried the point past it, within the margin, is retried as a natural step onto it */
    if (opt->monotonic && run->n >= 1 && run->dir * (f - opt->end_hz) > 1e-9) {
        rths_error_set(err, RTHS_EFAIL, "the correction carried the point past the end to %.6g Hz",
                       f);
        return BOUND_PAST_END;
    }
    if (opt->monotonic && run->n >= 1 &&
        run->dir * (sol->omega_rad_s - run->pts[run->n - 1].sol.omega_rad_s) <= 0) {
        rths_error_set(err, RTHS_EFAIL,
                       "the frequency moved back to %.6g Hz on a branch without folds", f);
        return BOUND_MOVED_BACK;
    }
    return BOUND_OK;
}

/* Predict, correct, then accept or retry. Returns RTHS_OK (*stop = 1 when the run ends
 * normally) or an error status (rig fault, point handler). */
static int run_step(cont_run *run, rths_progress_fn on_progress, int *stop, rths_error *err) {
    cont_prediction pr;
    follow_amplitude_scale(run);
    cont_predict(run, &pr);
    int rc = rths_corrector_solve(run->corr, pr.u, pr.omega_rad_s, &pr.arc, err);
    int evals;
    double rig_time;
    rths_corrector_counters(run->corr, &evals, NULL, &rig_time);
    run->pts[run->n].trust_actions += pr.trust_declined + rths_corrector_trust_actions(run->corr);
    run->res->evaluations += evals;
    run->res->rig_time_s += rig_time;
    const rths_solution *sol = rths_corrector_solution(run->corr);
    if (on_progress)
        on_progress(run->user, run->n, sol->omega_rad_s / (2 * M_PI), sol->residual_norm_m,
                    run->res->evaluations, rc == RTHS_OK);
    int leave = 0, bound = rc == RTHS_OK ? out_of_bounds(run, sol, &leave, err) : 0;
    /* an arclength step that moved back on a branch without folds: the next attempt steps
     * forward in frequency (natural parameter), as far as the last secant went */
    if (bound == BOUND_MOVED_BACK && !pr.natural_fallback) {
        double last_hz = fabs(run->pts[run->n - 1].secant_omega) / (2 * M_PI);
        run->step_hz = fmax(last_hz, 0.1 * run->opt->initial_step_hz);
    }
    if (bound == BOUND_MOVED_BACK) run->natural_next = 1;
    if (bound == BOUND_PAST_END) {
        run->step_hz = fabs(run->opt->end_hz - run->pts[run->n - 1].sol.omega_rad_s / (2 * M_PI));
        run->natural_next = 1;
    }
    if (bound) {
        rc = RTHS_EFAIL;
        if (leave) {
            snprintf(run->res->stop_reason, sizeof run->res->stop_reason, "%s", err->msg);
            run->res->stopped_short = 1;
            *stop = 1;
            return RTHS_OK;
        }
    }
    if (rc == RTHS_OK) {
        int status = on_accept(run, &pr);
        *stop = status != RTHS_OK;
        return status;
    }
    if (rths_rig_get_fault(run->rig) != RTHS_RIG_OK || !isfinite(sol->residual_norm_m)) {
        snprintf(run->res->stop_reason, sizeof run->res->stop_reason, "%s", err->msg);
        *stop = 1;
        return RTHS_EFAIL;
    }
    /* a response below the measured noise, or measurements the rig corrupted (clipped,
     * saturated, late) at the point itself: a smaller step meets the same rig, so retrying only
     * spends rig time before the same verdict */
    rths_corrector_outcome outcome = rths_corrector_status(run->corr);
    if (outcome == RTHS_CORRECTOR_BELOW_NOISE || outcome == RTHS_CORRECTOR_REFUSED) {
        snprintf(run->res->stop_reason, sizeof run->res->stop_reason, "%s", err->msg);
        run->res->stopped_short = 1;
        *stop = 1;
        return RTHS_EFAIL;
    }
    *stop = on_failure(run, &pr, err);
    return RTHS_OK;
}

int rths_continuation_run(rths_rig *rig, const rths_continuation_options *opt,
                          const rths_settle_options *settle, const rths_newton_options *newton,
                          int harmonics, double amplitude_n, const rths_point *resume, int n_resume,
                          rths_point_fn on_point, rths_progress_fn on_progress, void *user,
                          rths_continuation_result *res, rths_error *err) {
    rths_zero_problem problem;
    rths_rig_problem ctx;
    rths_rig_problem_init(&problem, &ctx, rig, settle, harmonics, amplitude_n);
    return rths_continuation_run_problem(&problem, rig, opt, newton, harmonics, resume, n_resume,
                                         on_point, on_progress, user, res, err);
}

int rths_continuation_run_problem(const rths_zero_problem *problem, rths_rig *rig,
                                  const rths_continuation_options *opt,
                                  const rths_newton_options *newton, int harmonics,
                                  const rths_point *resume, int n_resume, rths_point_fn on_point,
                                  rths_progress_fn on_progress, void *user,
                                  rths_continuation_result *res, rths_error *err) {
    cont_run run = {.rig = rig, .on_point = on_point, .user = user};
    int rc = run_init(&run, opt, harmonics, res, err);
    if (!rc) rc = rths_corrector_create(problem, newton, &run.corr, err);
    if (!rc) rc = run_resume(&run, resume, n_resume, err);
    int stop = 0;
    while (!rc && !stop && !res->reached_end && run.n < opt->max_points)
        rc = run_step(&run, on_progress, &stop, err);
    if (!res->reached_end && !res->stop_reason[0])
        snprintf(res->stop_reason, sizeof res->stop_reason, "reached the point limit (%d)",
                 opt->max_points);
    rths_corrector_destroy(run.corr);
    free(run.pts);
    free(run.folds.svals);
    return rc;
}
