/* The Newton-Broyden corrector with line search as an object: life cycle, one step, the saved
 * record, and the predictors' access to what it learnt. */
#include "iterate/corrector_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void rths_settle_defaults(rths_settle_options *opt, int paper) {
    memset(opt, 0, sizeof *opt);
    opt->average_periods = paper ? 10 : 4;
    /* The seed waits a fixed time; 40 periods is ~3 s at 13.5 Hz, several decay times of the
     * PD-damped rig. The adaptive wait stops as soon as the transient is predicted to be gone. */
    opt->fixed_wait_periods = paper ? 40 : 0;
    /* The numerical storey above the interface, held by the grounding controller, rings near
     * 10 Hz; against a 12-14 Hz forcing that beats every 3-5 periods, and a steady-state judgement
     * from fewer periods can take a beat's flat stretch for steady state (at resonance the
     * leftover transient then shows as errors of 4-5 standard errors) */
    opt->min_wait_periods = 8;
    opt->max_wait_periods = 400;
    opt->abs_tolerance_m = 1e-10;
    opt->rel_tolerance = 3e-4;
    /* docs/method.md, "One evaluation": with the noise measured (every coefficient's own
     * scatter, the numerical side's 2-4 times the laser's on the seed), a change within 1.5 times
     * its noise-alone size: pure noise exceeds that with probability 6 % (4 coefficients,
     * chi-square) and is accepted at once, while a transient may add only about 1.1 times the
     * noise's change. 3 let slow tails through on the bilinear seed (63 of 70 points within 3
     * standard errors of the truth against 68 at 1.5) */
    opt->noise_factor = 1.5;
}

void rths_newton_defaults(rths_newton_options *opt, int paper) {
    memset(opt, 0, sizeof *opt);
    opt->max_iterations = 12;
    opt->rel_tolerance = 1e-3;
    opt->abs_tolerance_m = 1e-9;
    opt->noise_factor = 3.0;
    opt->fd_step_rel = 0.05;
    opt->fd_step_min_m = 1e-7;
    opt->fd_step_omega_rel = 2e-3;
    opt->min_damping = 1.0 / 16.0;
    opt->fresh_jacobian = paper ? 1 : 0;
    opt->report_matched = paper ? 0 : 1;
    opt->step_limit = 2.0;
    /* docs/method.md, "Iteration and continuation": 1.8 times the anchor (the last point's size
     * times its last growth) lets through every prediction of the demo and the examples (at most
     * 1.35 times less than it) and kept the cantilever's wild one out */
    opt->trust_growth = 1.8;
    /* docs/method.md, "One evaluation": pure noise exceeds 5 standard errors in amplitude with
     * probability exp(-25 / 2) = 4e-6 (a Rayleigh tail), so no point of any sweep is accepted
     * from noise alone, and an accepted amplitude is known to 20 % or better from noise */
    opt->min_snr = 5.0;
}

int rths_corrector_create(const rths_zero_problem *problem, const rths_newton_options *opt,
                          rths_corrector **out, rths_error *err) {
    *out = NULL;
    int dofs = problem->interface_dofs > 1 ? problem->interface_dofs : 1;
    if (problem->n < 1 || problem->n > 2 * RTHS_MAX_HARMONICS || !problem->eval ||
        problem->harmonics < 0 || (problem->harmonics && problem->n != 2 * problem->harmonics))
        return rths_error_set(err, RTHS_EINPUT,
                              "zero problem: %d unknowns (%d harmonics) is not 1..%d (2 per "
                              "harmonic)",
                              problem->n, problem->harmonics, 2 * RTHS_MAX_HARMONICS);
    if (dofs > RTHS_MAX_INTERFACE_DOFS ||
        (dofs > 1 && (!problem->harmonics || problem->harmonics % dofs)))
        return rths_error_set(err, RTHS_EINPUT,
                              "zero problem: %d interface DoFs do not share %d Fourier pairs "
                              "evenly (at most %d DoFs)",
                              dofs, problem->harmonics, RTHS_MAX_INTERFACE_DOFS);
    rths_corrector *c = calloc(1, sizeof *c);
    if (!c) return rths_error_set(err, RTHS_EFAIL, "out of memory for the corrector");
    c->problem = *problem;
    c->opt = *opt;
    c->n = problem->n;
    c->harmonics = problem->harmonics;
    c->dofs = dofs;
    c->m = c->n;
    c->default_amp_scale = 1e-4;
    c->default_omega_scale = 1.0;
    c->trust_radius = INFINITY;
    *out = c;
    return RTHS_OK;
}

void rths_corrector_destroy(rths_corrector *c) {
    free(c);
}

void rths_corrector_set_scales(rths_corrector *c, double amplitude_scale_m,
                               double omega_scale_rad_s) {
    c->default_amp_scale = amplitude_scale_m;
    c->default_omega_scale = omega_scale_rad_s;
}

void rths_corrector_rescale_amplitude(rths_corrector *c, double old_scale_m, double new_scale_m) {
    /* d(Phi / a)/d(omega / s): only the frequency column depends on the amplitude scale a */
    for (int i = 0; i < c->n; i++) {
        c->mem.jacobian[i + c->n * LD] *= old_scale_m / new_scale_m;
        c->mem.response_jacobian[i + c->n * LD] *= old_scale_m / new_scale_m;
    }
}

static int arc_satisfied(const rths_corrector *c, const corrector_point *p) {
    /* the arclength row is linear: after a full step it holds to rounding; 1e-6 of a scaled unit
     * is far below any physical resolution */
    return c->m == c->n || fabs(p->phi[c->n]) < 1e-6;
}

static int converged(const rths_corrector *c, const corrector_point *p) {
    return p->within && arc_satisfied(c, p);
}

static int newton_step(rths_corrector *c, double *du, double *fraction, double *trust_t);

/* A point within tolerance: accepted (its report finished) unless its response lies below the
 * noise floor, which stops the correction (RTHS_CORRECTOR_BELOW_NOISE) or, when the options
 * accept such points, is flagged in the solution. */
static int accept_point(rths_corrector *c, rths_error *err) {
    if (corrector_below_noise_floor(c)) {
        if (!c->opt.accept_below_noise) {
            c->status = RTHS_CORRECTOR_BELOW_NOISE;
            return RTHS_OK;
        }
        c->cur.sol.below_noise_floor = 1;
    }
    c->cur.sol.converged = 1;
    int rc = corrector_finish(c, err);
    c->status = RTHS_CORRECTOR_CONVERGED;
    return rc;
}

/* The reported amplitude's largest relative standard error over the interface DoFs, that DoF,
 * and whether the step's term (the mismatch times the sensitivity's uncertainty) is the larger
 * of its two terms there; *noise_rel: that DoF's noise term, relative. */
static double reported_rel_se(const rths_corrector *c, int *step_dominates, double *noise_rel) {
    const rths_solution *s = &c->cur.sol;
    int dofs = s->interface_dofs > 1 ? s->interface_dofs : 1;
    double worst = 0;
    *step_dominates = 0;
    *noise_rel = 0;
    for (int d = 0; d < dofs; d++) {
        double amp = dofs > 1 ? s->dof_amplitude_m[d] : s->amplitude_m;
        double se = dofs > 1 ? s->dof_amplitude_se_m[d] : s->amplitude_se_m;
        /* a DoF that does not move has no relative error to bound (and an infinite one would
         * spend the point's budget and reach the journal as a non-number) */
        if (!(amp > 0) || !isfinite(se)) continue;
        double rel = se / amp;
        if (!(rel <= worst)) {
            worst = rel;
            *step_dominates = c->se_step_m[d] > c->se_noise_m[d];
            *noise_rel = c->se_noise_m[d] / amp;
        }
    }
    return worst;
}

/* The point's rig time against iteration.max_rig_s_per_point: its tally's (every evaluation of
 * the point), or without one this correction's. */
static double point_rig_s(const rths_corrector *c) {
    const rths_settle_options *st = c->problem.settle;
    return st->tally ? st->tally->rig_time_s : c->rig_time_s;
}

static double point_budget_s(const rths_corrector *c) {
    const rths_settle_options *st = c->problem.settle;
    return st->max_rig_s_per_point > 0 ? st->max_rig_s_per_point : RTHS_SETTLE_MAX_RIG_S_PER_POINT;
}

/* Whether rec is a waiting evaluation that says how long it averaged. */
static int averaging_known(const rths_residual *rec) {
    return !rec->eval.fitted && rec->eval.frequency_hz > 0 && rec->eval.average_periods > 0 &&
           rec->eval.average_periods / rec->eval.frequency_hz <= rec->rig_time_s;
}

/* The rig time of a record like rec's with its noise's relative error times `shrink`: a waiting
 * evaluation keeps its wait and lengthens its averaging by 1/shrink^2; a fitted one (whose standard
 * error carries its poles' uncertainty as well) or one that does not say how it averaged lengthens
 * as a whole. */
static double record_cost_s(const rths_residual *rec, double shrink) {
    if (!averaging_known(rec)) return rec->rig_time_s / (shrink * shrink);
    double averaging_s = rec->eval.average_periods / rec->eval.frequency_hz;
    return rec->rig_time_s - averaging_s + averaging_s / (shrink * shrink);
}

/* Further steps at most per point (each one evaluation): the mismatch falls by the Newton
 * step's contraction each time, so a few suffice unless the noise bounds it */
enum { ACCURACY_MAX_STEPS = 6 };

/* Accuracy on demand (docs/method.md, "Accuracy on demand"): iteration.target_rel_se bounds the
 * REPORTED amplitude's relative standard error. While it is above the target and the point's
 * rig budget lasts, one more Newton step from the accepted point (its mismatch, the step's term,
 * shrinks with it), and when the noise's term is the larger the evaluation's own target tightened
 * in proportion (a longer record); the step's evaluation is taken when within tolerance (and
 * joins the model's history either way), and the report is made again. A point still above the
 * target is flagged in its solution's evaluation (se_target_missed, amplitude_rel_se the reported
 * one) and noted. */
static int accuracy_on_demand(rths_corrector *c, rths_error *err) {
    const rths_settle_options *st = c->problem.settle;
    if (!st || !(st->target_rel_se > 0) || c->status != RTHS_CORRECTOR_CONVERGED ||
        c->harmonics == 0)
        return RTHS_OK;
    double target = st->target_rel_se;
    int step_dominates = 0, rc = RTHS_OK;
    double noise_rel = 0, rel = reported_rel_se(c, &step_dominates, &noise_rel);
    double *eval_target = c->problem.evaluation_target_rel_se;
    for (int k = 0; k < ACCURACY_MAX_STEPS && rel > target && point_rig_s(c) < point_budget_s(c);
         k++) {
        double du[LD], fraction = 1.0, trust_t = 1.0;
        if (newton_step(c, du, &fraction, &trust_t) != 0) break;
        /* the noise's term: the next record's relative error at most half the last one's (its
         * record four times as long, about; a step at a time, so one record does not spend the
         * point's budget on a goal it cannot reach) */
        double shrink = step_dominates || !eval_target ? 1.0 : fmax(0.5, target / noise_rel);
        /* a step whose record would overrun the budget is not begun: a record is not cut short
         * (a waiting record's noise falls with its averaging alone, so only that lengthens) */
        if (point_rig_s(c) + record_cost_s(&c->cur.rec, shrink) > point_budget_s(c)) break;
        if (shrink < 1.0) {
            double now =
                c->cur.rec.eval.amplitude_rel_se > 0 ? c->cur.rec.eval.amplitude_rel_se : target;
            *eval_target = now * shrink;
        }
        corrector_point *trial = malloc(sizeof *trial);
        if (!trial) return rths_error_set(err, RTHS_EFAIL, "out of memory in the corrector");
        *trial = c->cur; /* what the evaluation does not set (as the line search's trials) */
        double ut[LD];
        for (int i = 0; i < LD; i++)
            ut[i] = c->cur.u[i] + (i < c->m ? du[i] : 0.0);
        rc = corrector_evaluate(c, ut, trial, RTHS_EVALUATION_ACCURACY_STEP, 0.0, err);
        if (rc && c->refused) { /* a corrupted trial: the accepted point stands */
            c->refused = 0;
            rc = RTHS_OK;
            free(trial);
            break;
        }
        if (!rc && converged(c, trial)) {
            corrector_secant_update(c, trial);
            corrector_point previous = c->cur;
            c->cur = *trial;
            if (corrector_below_noise_floor(c) && !c->opt.accept_below_noise) {
                c->cur = previous; /* the accepted point stands */
            } else {
                c->cur.sol.below_noise_floor = corrector_below_noise_floor(c);
                c->cur.sol.converged = 1;
            }
        }
        free(trial);
        if (rc) break;
        /* the step's evaluation joined the history and the pooled noise either way */
        if ((rc = corrector_finish(c, err))) break;
        rel = reported_rel_se(c, &step_dominates, &noise_rel);
    }
    if (eval_target) *eval_target = 0;
    if (rc) return rc;
    c->cur.sol.eval.amplitude_rel_se = rel;
    c->cur.sol.eval.se_target_missed = rel > target;
    if (rel > target && st->note) {
        char line[512];
        snprintf(line, sizeof line,
                 "point at %.6g Hz: the reported amplitude's relative standard error %.3g is above "
                 "iteration.target_rel_se %.3g after %.3g of the point's %.3g rig s "
                 "(iteration.max_rig_s_per_point; %s the larger term): not met within the "
                 "budget",
                 c->cur.sol.frequency_hz, rel, target, point_rig_s(c), point_budget_s(c),
                 step_dominates ? "the mismatch's step" : "the noise");
        st->note(st->note_user, line);
    }
    return RTHS_OK;
}

static int accept_converged(rths_corrector *c, rths_error *err) {
    int rc = accept_point(c, err);
    if (!rc) rc = accuracy_on_demand(c, err);
    return rc;
}

/* Scales, the arclength row and the per-correction counters for a new correction. */
static void begin(rths_corrector *c, const rths_arclength *arc) {
    int n = c->n;
    memset(&c->arc, 0, sizeof c->arc);
    if (arc) c->arc = *arc;
    c->m = c->arc.active ? n + 1 : n;
    double amp_scale =
        c->arc.amplitude_scale_m > 0 ? c->arc.amplitude_scale_m : c->default_amp_scale;
    double om_scale =
        c->arc.omega_scale_rad_s > 0 ? c->arc.omega_scale_rad_s : c->default_omega_scale;
    for (int j = 0; j < n; j++)
        c->scale[j] = amp_scale;
    c->scale[n] = om_scale;
    c->evaluations = 0;
    c->iterations = 0;
    c->rig_time_s = 0;
    c->jacobian_here = 0;
    c->fresh = 0;
    c->repaired = 0;
    c->status = RTHS_CORRECTOR_CONTINUE;
    c->trust_actions = 0;
    c->refused = 0;
    c->refused_trials = 0;
    c->late_samples = c->clipped_samples = c->saturated_samples = c->samples_read = 0;
    c->remeasured = c->refused_evaluations = 0;
    c->trust_radius = c->trust_anchor_m > 0 && c->opt.trust_growth > 0
                          ? c->opt.trust_growth * c->trust_anchor_m / amp_scale
                          : INFINITY;
    /* earlier corrections' noise counts half per correction: close in frequency, similar noise */
    for (int i = 0; i < n; i++) {
        c->mem.noise_ss[0][i] *= 0.5;
        c->mem.noise_ss[1][i] *= 0.5;
    }
    c->mem.noise_dof *= 0.5;
    memset(&c->cur, 0, sizeof c->cur);
    c->cur.sol.harmonics = c->harmonics;
}

/* Euclidean size of the target part of unknowns u (scaled, or in metres). */
static double target_norm(const rths_corrector *c, const double *u) {
    double size = 0;
    for (int i = 0; i < c->n; i++)
        size += u[i] * u[i];
    return sqrt(size);
}

void rths_corrector_set_trust_anchor(rths_corrector *c, double anchor_m) {
    c->trust_anchor_m = anchor_m > 0 && isfinite(anchor_m) ? anchor_m : 0;
}

int rths_corrector_trust_allows(const rths_corrector *c, const double *u_m) {
    if (!(c->trust_anchor_m > 0 && c->opt.trust_growth > 0)) return 1;
    return target_norm(c, u_m) <= c->opt.trust_growth * c->trust_anchor_m;
}

const char *rths_evaluation_role_name(rths_evaluation_role role) {
    switch (role) {
    case RTHS_EVALUATION_PREDICTION:
        return "prediction";
    case RTHS_EVALUATION_JACOBIAN:
        return "jacobian";
    case RTHS_EVALUATION_STEP:
        return "step";
    case RTHS_EVALUATION_DAMPED_STEP:
        return "damped_step";
    case RTHS_EVALUATION_GAIN_PROBE:
        return "gain_probe";
    case RTHS_EVALUATION_ACCURACY_STEP:
        return "accuracy_step";
    }
    return "unknown";
}

int rths_corrector_quadratic_predictor(const rths_corrector *c) {
    return c->opt.quadratic_predictor;
}

int rths_corrector_trust_actions(const rths_corrector *c) {
    return c->trust_actions;
}

/* A problem error rc: when the evaluation was refused (corrupted twice), the correction ends
 * as RTHS_CORRECTOR_REFUSED, the error's message naming the counts. Returns rc. */
static int refusal(rths_corrector *c, int rc) {
    if (rc && c->refused) c->status = RTHS_CORRECTOR_REFUSED;
    return rc;
}

static int corrector_set(rths_corrector *c, const double *u0, double omega_rad_s,
                         const rths_arclength *arc, rths_error *err) {
    begin(c, arc);
    int n = c->n;
    double u[LD] = {0};
    for (int i = 0; i < n; i++)
        u[i] = u0[i] / c->scale[i];
    u[n] = omega_rad_s / c->scale[n];
    c->cur.sol.omega_rad_s = omega_rad_s;
    /* a prediction beyond the trust region is shrunk onto it before the rig sees it */
    double size = target_norm(c, u);
    if (size > c->trust_radius) {
        for (int i = 0; i < n; i++)
            u[i] *= c->trust_radius / size;
        c->trust_actions++;
    }
    int rc = corrector_evaluate(c, u, &c->cur, RTHS_EVALUATION_PREDICTION, 0.0, err);
    if (rc) return rc;
    if (converged(c, &c->cur)) return accept_converged(c, err);
    /* no carried Jacobian, the seed's flowchart, or a carried one without the frequency column
     * (natural sweep before) on an arclength step: measure */
    if (!c->mem.have_jacobian || c->opt.fresh_jacobian ||
        (c->m > n && fabs(c->mem.jacobian[n * LD]) == 0.0))
        return corrector_fd_jacobian(c, err);
    return RTHS_OK;
}

int rths_corrector_set(rths_corrector *c, const double *u0, double omega_rad_s,
                       const rths_arclength *arc, rths_error *err) {
    return refusal(c, corrector_set(c, u0, omega_rad_s, arc, err));
}

/* Rig safety, with or without a trust region: shortens du to at most step_limit times the larger
 * of the current target and the measured numerical response, scaling *fraction alike. */
static void limit_step(const rths_corrector *c, double *du, double *fraction) {
    /* A step from a stale (Broyden) or noisy Jacobian can be huge, and on a real rig the trial
     * evaluation itself would trip a limit before the line search could reject it. */
    if (!(c->opt.step_limit > 0)) return;
    int n = c->n;
    double tnorm = 0, dnorm = 0, rnorm = 0;
    for (int i = 0; i < n; i++) {
        tnorm += c->cur.u[i] * c->cur.u[i];
        dnorm += du[i] * du[i];
    }
    tnorm = sqrt(tnorm);
    dnorm = sqrt(dnorm);
    const double *ref = c->cur.rec.reference;
    int N = c->harmonics;
    for (int k = 0; k < N; k++)
        rnorm += ref[k] * ref[k] + ref[N + k] * ref[N + k];
    for (int i = 0; !N && i < n; i++)
        rnorm += ref[i] * ref[i];
    rnorm = sqrt(rnorm) / c->scale[0];
    double limit = c->opt.step_limit * fmax(tnorm, rnorm);
    if (dnorm > limit) {
        for (int i = 0; i < c->m; i++)
            du[i] *= limit / dnorm;
        *fraction *= limit / dnorm;
    }
}

/* Largest fraction t in [0, 1] of the step du that keeps the targets of u + t du inside the trust
 * region (|u + t du| <= radius, a quadratic in t). */
static double trust_fraction(const rths_corrector *c, const double *u, const double *du) {
    if (!isfinite(c->trust_radius)) return 1.0;
    double a = 0, b = 0, size = 0;
    for (int i = 0; i < c->n; i++) {
        a += du[i] * du[i];
        b += u[i] * du[i];
        size += u[i] * u[i];
    }
    double r2 = c->trust_radius * c->trust_radius, end = size + 2 * b + a;
    if (end <= r2 || !(a > 0)) return 1.0;
    double disc = b * b - a * (size - r2);
    if (disc < 0) return 0.0;
    return fmax(0.0, (-b + sqrt(disc)) / a);
}

/* The Newton step du of the extended system (J over the unknowns in use, plus the arclength row),
 * limited for rig safety and to the trust region; *fraction is what remains of the full Newton
 * step (1: all of it). Returns -1 if the system is singular. */
static int newton_step(rths_corrector *c, double *du, double *fraction, double *trust_t) {
    int n = c->n, m = c->m;
    double a[LD * LD];
    for (int j = 0; j < m; j++) {
        for (int i = 0; i < n; i++)
            a[i + j * LD] = c->mem.jacobian[i + j * LD];
        if (m > n) a[n + j * LD] = c->arc.tangent[j];
    }
    for (int i = 0; i < m; i++)
        du[i] = -c->cur.phi[i];
    if (solve_small(m, a, LD, du) != 0) return -1;
    *fraction = 1.0;
    limit_step(c, du, fraction);
    double t = *trust_t = trust_fraction(c, c->cur.u, du);
    if (t < 1.0) {
        for (int i = 0; i < m; i++)
            du[i] *= t;
        *fraction *= t;
        c->trust_actions++;
    }
    return 0;
}

/* Backtracking line search on the extended residual norm (erratum 5): halves the step down to
 * min_damping, or with full_only stops after a full step that was measured and did not reduce
 * the residual (*lambda_out 1, its evaluation in *trial; a refused full step is halved as
 * before). Returns 1 with *trial when the residual fell, else 0; a problem error comes back in
 * *rc. */
static int line_search(rths_corrector *c, const double *du, corrector_point *trial,
                       double *lambda_out, int full_only, int *rc, rths_error *err) {
    *trial = c->cur;
    for (double lambda = 1.0; lambda >= c->opt.min_damping; lambda *= 0.5) {
        *lambda_out = lambda;
        double ut[LD];
        for (int i = 0; i < c->m; i++)
            ut[i] = c->cur.u[i] + lambda * du[i];
        for (int i = c->m; i < LD; i++)
            ut[i] = c->cur.u[i];
        rths_evaluation_role role =
            lambda == 1.0 ? RTHS_EVALUATION_STEP : RTHS_EVALUATION_DAMPED_STEP;
        if ((*rc = corrector_evaluate(c, ut, trial, role, lambda, err))) {
            /* a trial whose measurement was corrupted (clipped, saturated) is a step too far:
             * a shorter one is tried, as for a residual that grew */
            if (!c->refused) return 0;
            *rc = RTHS_OK;
            c->refused = 0;
            c->refused_trials++;
            continue;
        }
        if (trial->ext < c->cur.ext) return 1;
        if (full_only && lambda == 1.0) return 0;
    }
    return 0;
}

/* docs/method.md, "The corrector": measured on the bilinear example, every one of 29 such
 * repairs from within 40 tolerances was followed by a full step that reduced the residual; on the
 * two-interface Duffing example's cold start, 160 tolerances off, the secant of so long a step
 * misled the steps after it and the first point no longer converged in its 12 iterations */
static const double SECANT_REPAIR_MAX_TOLERANCES = 50.0;

/* Whether a failed full step from the current iterate should repair the carried Jacobian with
 * its own trial instead of being halved: the model is not fresh (a fresh one that fails is
 * halved, then the point is stuck), not yet repaired in this correction, and the iterate is
 * close enough to the solution that the step's secant is the rig's local slope along it. */
static int repair_on_failure(const rths_corrector *c) {
    return c->opt.secant_repair && !c->fresh && !c->repaired &&
           c->cur.sol.residual_to_tolerance <= SECANT_REPAIR_MAX_TOLERANCES;
}

/* The Newton step points out of the trust region from its boundary. A carried or updated model
 * is not trusted that far: measure a fresh Jacobian here. A fresh one is the best model the rig
 * gives: its step counts as the cause to widen the region (twice; the line search still judges
 * the step). */
static int trust_blocked(rths_corrector *c, rths_error *err) {
    if (!c->fresh) return corrector_fd_jacobian(c, err);
    c->trust_radius *= 2;
    c->trust_actions++;
    return RTHS_OK;
}

static int corrector_iterate(rths_corrector *c, rths_error *err) {
    if (c->status != RTHS_CORRECTOR_CONTINUE) return RTHS_OK;
    if (c->iterations >= c->opt.max_iterations) {
        c->status = RTHS_CORRECTOR_MAX_ITER;
        return RTHS_OK;
    }
    c->iterations++;
    double du[LD], fraction = 1.0, trust_t = 1.0, lambda = 1.0;
    if (newton_step(c, du, &fraction, &trust_t) != 0) {
        if (c->fresh) {
            c->status = RTHS_CORRECTOR_SINGULAR;
            return RTHS_OK;
        }
        return corrector_fd_jacobian(c, err);
    }
    if (trust_t < c->opt.min_damping) return trust_blocked(c, err);
    double promised = fraction * c->cur.ext; /* the linear model's fall of the residual norm */
    corrector_point *trial = malloc(sizeof *trial);
    if (!trial) return rths_error_set(err, RTHS_EFAIL, "out of memory in the corrector");
    int repair = repair_on_failure(c);
    int rc = RTHS_OK, accepted = line_search(c, du, trial, &lambda, repair, &rc, err);
    /* a step the trust region cut short, taken whole, that reduced the residual as its model
     * promised: the model is borne out up to the boundary, so the solution may lie beyond it */
    if (!rc && accepted && trust_t < 1.0 && lambda == 1.0 &&
        c->cur.ext - trial->ext >= 0.75 * promised)
        c->trust_radius *= 2;
    if (!rc && accepted) {
        corrector_secant_update(c, trial);
        c->fresh = 0;
        c->jacobian_here = 1;
        c->cur = *trial;
        if (converged(c, &c->cur)) rc = accept_converged(c, err);
    } else if (!rc && repair && lambda == 1.0) {
        /* the failed trial is a measured secant along the step: the carried model was wrong
         * along it (near a fold, or a Broyden update that went stale), and one evaluation now
         * corrects it where halving and a fresh finite-difference Jacobian cost up to 5 + n + 1 */
        c->repaired = 1;
        corrector_secant_update(c, trial);
        c->jacobian_here = 1;
    } else if (!rc && c->fresh) {
        c->status = RTHS_CORRECTOR_STUCK; /* a fresh Jacobian could not reduce the residual */
    } else if (!rc) {
        rc = corrector_fd_jacobian(c, err);
    }
    free(trial);
    if (!rc && c->status == RTHS_CORRECTOR_CONTINUE && c->iterations >= c->opt.max_iterations)
        c->status = RTHS_CORRECTOR_MAX_ITER;
    return rc;
}

int rths_corrector_iterate(rths_corrector *c, rths_error *err) {
    return refusal(c, corrector_iterate(c, err));
}

rths_corrector_outcome rths_corrector_status(const rths_corrector *c) {
    return c->status;
}

const rths_solution *rths_corrector_solution(const rths_corrector *c) {
    return &c->cur.sol;
}

const rths_residual *rths_corrector_residual(const rths_corrector *c) {
    return &c->cur.rec;
}

void rths_corrector_unknowns(const rths_corrector *c, double *u) {
    for (int i = 0; i < c->n; i++)
        u[i] = c->cur.u[i] * c->scale[i];
}

void rths_corrector_counters(const rths_corrector *c, int *evaluations, int *iterations,
                             double *rig_time_s) {
    if (evaluations) *evaluations = c->evaluations;
    if (iterations) *iterations = c->iterations;
    if (rig_time_s) *rig_time_s = c->rig_time_s;
}

int rths_corrector_solve(rths_corrector *c, const double *u0, double omega_rad_s,
                         const rths_arclength *arc, rths_error *err) {
    int rc = rths_corrector_set(c, u0, omega_rad_s, arc, err);
    while (!rc && c->status == RTHS_CORRECTOR_CONTINUE)
        rc = rths_corrector_iterate(c, err);
    if (rc) return rc;
    if (c->status == RTHS_CORRECTOR_CONVERGED) return RTHS_OK;
    if (c->status == RTHS_CORRECTOR_SINGULAR)
        return rths_error_set(err, RTHS_EFAIL, "singular Jacobian");
    const rths_solution *s = &c->cur.sol;
    if (c->status == RTHS_CORRECTOR_BELOW_NOISE)
        return rths_error_set(
            err, RTHS_EFAIL,
            "the point at %.6g Hz is below the noise floor: the interface response is not "
            "clearly above the measured noise; its best-resolved DoF, interface DoF %d, moves "
            "%.3g (m, or rad for a rotation) against a floor of %.3g = iteration.min_snr %g x "
            "its mismatch's measured standard error %.3g (signal-to-noise %.3g). The forcing is "
            "too small for this structure, or its masses or stiffnesses are in the wrong units; "
            "--force accepts such points and flags them",
            s->omega_rad_s / (2 * M_PI), s->snr_dof + 1, s->snr_amplitude_m, s->noise_floor_m,
            c->opt.min_snr, s->noise_floor_m / c->opt.min_snr, s->snr);
    char trials[160] = "";
    if (c->refused_trials > 0)
        snprintf(trials, sizeof trials,
                 " (%d trial steps were refused: their measurements held clipped or saturated "
                 "samples)",
                 c->refused_trials);
    return rths_error_set(
        err, RTHS_EFAIL,
        "corrector did not converge at %.6g Hz: residual %.3g times its tolerance "
        "(residual %.3g m, tolerance %.3g m) after %d iterations%s",
        s->omega_rad_s / (2 * M_PI), s->residual_to_tolerance, s->residual_norm_m, s->tolerance_m,
        c->iterations, trials);
}

void rths_corrector_integrity(const rths_corrector *c, long *late_samples,
                              long *clipped_demand_samples, long *saturated_sensor_samples,
                              long *samples_read, int *remeasured, int *refused) {
    if (late_samples) *late_samples = c->late_samples;
    if (clipped_demand_samples) *clipped_demand_samples = c->clipped_samples;
    if (saturated_sensor_samples) *saturated_sensor_samples = c->saturated_samples;
    if (samples_read) *samples_read = c->samples_read;
    if (remeasured) *remeasured = c->remeasured;
    if (refused) *refused = c->refused_evaluations;
}

void rths_corrector_forget_jacobian(rths_corrector *c) {
    c->mem.have_jacobian = 0;
}

int rths_corrector_lti_predict(rths_corrector *c, double omega_rad_s, double *u) {
    int P = c->harmonics;
    lti_model model;
    if (!c->mem.lti || P == 0 || lti_model_fit(&c->mem, P, c->dofs, omega_rad_s, NULL, &model) != 0)
        return -1;
    double z[LD];
    for (int k = 0; k < model.harmonics; k++)
        for (int d = 0; d < model.dofs; d++) {
            int p = d * model.harmonics + k;
            z[p] = creal(model.z[k][d]);
            z[P + p] = cimag(model.z[k][d]);
        }
    /* a model that puts the solution beyond the trust region is not believed (nor its gains) */
    if (!rths_corrector_trust_allows(c, z)) return -2;
    memcpy(u, z, sizeof(double) * (size_t)(2 * P));
    lti_model_apply(&model, c->mem.jacobian, c->mem.response_jacobian);
    return 0;
}

void rths_corrector_seed_jacobians(rths_corrector *c, const double *jacobian,
                                   const double *response_jacobian) {
    if (!c->mem.have_jacobian) return;
    for (int j = 0; j < c->n; j++)
        for (int i = 0; i < c->n; i++) {
            c->mem.jacobian[i + j * LD] = jacobian[i + j * LD];
            c->mem.response_jacobian[i + j * LD] = response_jacobian[i + j * LD];
        }
    if (c->mem.lti && c->harmonics > 0) {
        lti_project(c->mem.jacobian, c->harmonics, c->dofs);
        lti_project(c->mem.response_jacobian, c->harmonics, c->dofs);
    }
}

int rths_correct(rths_rig *rig, const rths_settle_options *settle, const rths_newton_options *opt,
                 double amplitude_n, const rths_arclength *arc, rths_corrector_state *state,
                 rths_solution *sol, rths_error *err) {
    rths_zero_problem problem;
    rths_rig_problem ctx;
    int N = sol->harmonics;
    rths_rig_problem_init(&problem, &ctx, rig, settle, N, amplitude_n);
    rths_corrector *c = NULL;
    int rc = rths_corrector_create(&problem, opt, &c, err);
    if (!rc && state->length > 0) rc = rths_corrector_load(c, state, err);
    double u[LD];
    for (int k = 0; k < N; k++) {
        u[k] = sol->target_a[k];
        u[N + k] = sol->target_b[k];
    }
    if (!rc) rc = rths_corrector_solve(c, u, sol->omega_rad_s, arc, err);
    if (c) {
        *sol = c->cur.sol;
        rths_corrector_save(c, state);
    }
    rths_corrector_destroy(c);
    return rc;
}
