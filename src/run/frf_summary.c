/* summary.json of an FRF test: the run's totals and extremes, its points against the truth, the
 * folds, the integrity counts (also run.log's line and a failed run's message), the evaluations,
 * the actuator's limits and the experimental Floquet counts. */
#include "run/frf_internal.h"

#include "rths/rig_virtual.h"
#include "run/frf_outputs_internal.h"

#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* rths_json_summary_new plus what identifies the run's input. */
static json_object *summary_new(const rths_run_frf_options *opt) {
    json_object *o = rths_json_summary_new("frf");
    if (!o) return NULL;
    if (opt->config_path)
        json_object_object_add(o, "config_file", json_object_new_string(opt->config_path));
    json_object *sets = json_object_new_array();
    for (int i = 0; i < opt->n_overrides; i++)
        json_object_array_add(sets, json_object_new_string(opt->overrides[i]));
    json_object_object_add(o, "overrides", sets);
    if (opt->has_seed) json_object_object_add(o, "seed", json_object_new_uint64(opt->seed));
    return o;
}

static int write_summary_json(rths_report *rep, json_object *root, rths_error *err) {
    char *path = rths_report_path(rep, "summary.json");
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = rths_json_write(path, root, err);
    free(path);
    if (!rc) rths_report_log(rep, "wrote summary.json");
    return rc;
}

static int compare_int(const void *a, const void *b) {
    return (*(const int *)a > *(const int *)b) - (*(const int *)a < *(const int *)b);
}

typedef struct {
    int converged, evaluations, within_se[4], honest, compared;
    int measured_after_resume; /* points with the resumed mark (frf.csv's resumed column) */
    /* the accepted evaluations' integrity counts, summed, and the points with any */
    long late, clipped, saturated, samples_read;
    int points_late, points_clipped, points_saturated;
    /* points farther than FAR_FROM_FOLD_HZ from a fold of the truth, and those within 3 SE */
    int far, far_within_3se;
    /* points farther than STABLE_FOLD_HZ from a fold: labelled, and agreeing with the truth */
    int stable_compared, stable_agree;
    /* the experimental Floquet labels: measured, trustworthy, labelled stable / unstable /
     * undetermined, determined and agreeing with the fold-based label; farther than
     * STABLE_FOLD_HZ from a fold, determined and compared with the truth, agreeing with it, and
     * undetermined; the largest modulus within 1/2/3 standard errors of the truth's */
    int floquet_measured, floquet_trustworthy, floquet_labels[3], floquet_agree_label,
        floquet_compared, floquet_agree_truth, floquet_undetermined_far, floquet_se_compared,
        floquet_within_se[4];
    double
        max_z_honest; /* largest |A - truth| / SE of a point whose SE is honest, far from folds */
    double rig_time, max_h[4], median;
    /* with several interface DoFs on a linear structure, each DoF against the analytic FRF */
    double dof_max_err[RTHS_MAX_INTERFACE_DOFS];
    int dof_compared[RTHS_MAX_INTERFACE_DOFS], dof_within[RTHS_MAX_INTERFACE_DOFS][4];
} point_stats;

/* Near a fold the branch is vertical: a frequency error of a few mHz there is a large amplitude
 * error at the point's frequency, so the standard-error check counts the points away from folds
 * separately (5 mHz, a few times the hybrid test's fold location error), and the stability label
 * is compared from 2 mHz on (the fold's location error). */
static const double FAR_FROM_FOLD_HZ = 5e-3, STABLE_FOLD_HZ = 2e-3;

/* The experimental Floquet estimate of a point against the truth: its determined label against
 * the truth's stability (stable) away from folds, its largest modulus against the truth's. */
static void floquet_with_truth(const frf_state *run, const rths_point *pt, int stable,
                               double fold_hz, point_stats *ps) {
    const frf_floquet_point *f = frf_measured_floquet_point(run, pt->index);
    if (!f) return;
    double truth = frf_floquet_truth_at(run, pt->sol.frequency_hz, pt->sol.amplitude_m);
    if (isfinite(truth) && isfinite(f->max_abs_se)) {
        double z = fabs(f->max_abs - truth) / f->max_abs_se;
        ps->floquet_se_compared++;
        for (int k = 1; k <= 3; k++)
            ps->floquet_within_se[k] += z <= k;
    }
    if (!(fold_hz > STABLE_FOLD_HZ)) return;
    if (f->label == RTHS_FLOQUET_UNDETERMINED) {
        ps->floquet_undetermined_far++;
        return;
    }
    ps->floquet_compared++;
    ps->floquet_agree_truth += f->label == stable;
}

/* One point against the truth at its frequency on its branch: how many standard errors off
 * (counted in ps->within_se[1..3]) and whether its stability label agrees. linear_truth: the
 * analytic amplitude of a linear structure, solved once per point by the caller. */
static void compare_with_truth(const frf_state *run, const rths_point *pt, double linear_truth,
                               point_stats *ps) {
    int stable = 1;
    double f = pt->sol.frequency_hz, a = pt->sol.amplitude_m;
    double truth = run->setup->has_bilinear
                       ? rths_truth_branch_amplitude_m(run->setup, &run->truth, f, a, &stable)
                       : linear_truth;
    if (!isfinite(truth)) return;
    double z = fabs(a - truth) / pt->sol.amplitude_se_m;
    double fold_hz = rths_truth_fold_distance_hz(&run->truth, f);
    ps->compared++;
    for (int k = 1; k <= 3; k++)
        ps->within_se[k] += z <= k;
    if (fold_hz > FAR_FROM_FOLD_HZ) {
        ps->far++;
        ps->far_within_3se += z <= 3;
        if (pt->sol.amplitude_se_honest) ps->max_z_honest = fmax(ps->max_z_honest, z);
    }
    if (fold_hz > STABLE_FOLD_HZ) {
        ps->stable_compared++;
        ps->stable_agree += rths_point_stable(pt) == stable;
    }
    if (run->floquet.enabled) floquet_with_truth(run, pt, stable, fold_hz, ps);
}

/* The experimental Floquet counts that need no truth. */
static void floquet_statistics(const frf_state *run, point_stats *ps) {
    for (int i = 0; i < run->n && run->floquet.enabled; i++) {
        const frf_floquet_point *f = frf_measured_floquet_point(run, i);
        if (!f) continue;
        ps->floquet_measured++;
        ps->floquet_trustworthy += f->trustworthy;
        ps->floquet_labels[f->label + 1]++;
        ps->floquet_agree_label += f->label == rths_point_stable(&run->pts[i]);
    }
}

static json_object *floquet_json(const frf_state *run, const point_stats *ps) {
    json_object *o = json_object_new_object();
    const rths_floquet_measure_options *f = &run->floquet;
    json_object_object_add(o, "periods_per_point", json_object_new_int(f->periods));
    json_object_object_add(o, "perturbation_v", json_object_new_double(f->perturbation_v));
    json_object_object_add(o, "cutoff_hz", json_object_new_double(f->cutoff_hz));
    json_object_object_add(o, "samples_per_period", json_object_new_int(f->samples_per_period));
    json_object_object_add(o, "bootstrap_replicates",
                           json_object_new_int(f->fit.bootstrap_replicates));
    json_object_object_add(o, "determined_beyond_standard_errors",
                           json_object_new_double(f->fit.determined_se));
    json_object_object_add(o, "points_measured", json_object_new_int(ps->floquet_measured));
    json_object_object_add(o, "points_trustworthy", json_object_new_int(ps->floquet_trustworthy));
    json_object_object_add(o, "points_labelled_stable", json_object_new_int(ps->floquet_labels[2]));
    json_object_object_add(o, "points_labelled_unstable",
                           json_object_new_int(ps->floquet_labels[1]));
    json_object_object_add(o, "points_undetermined", json_object_new_int(ps->floquet_labels[0]));
    json_object_object_add(o, "points_agreeing_with_stable_label",
                           json_object_new_int(ps->floquet_agree_label));
    /* farther than STABLE_FOLD_HZ from a fold of the truth: the determined labels compared */
    json_object_object_add(o, "points_compared_with_truth",
                           json_object_new_int(ps->floquet_compared));
    json_object_object_add(o, "points_agreeing_with_truth",
                           json_object_new_int(ps->floquet_agree_truth));
    json_object_object_add(o, "points_undetermined_away_from_folds",
                           json_object_new_int(ps->floquet_undetermined_far));
    json_object_object_add(o, "points_with_standard_error_compared",
                           json_object_new_int(ps->floquet_se_compared));
    static const char *const within[] = {NULL, "points_within_1_standard_error_of_truth",
                                         "points_within_2_standard_errors_of_truth",
                                         "points_within_3_standard_errors_of_truth"};
    for (int k = 1; k <= 3; k++)
        json_object_object_add(o, within[k], json_object_new_int(ps->floquet_within_se[k]));
    json_object_object_add(o, "rig_time_s", json_object_new_double(run->floquet_rig_time_s));
    return o;
}

/* With several interface DoFs on a linear structure: every DoF's reported amplitude against the
 * analytic FRF at its frequency, truth[d] (largest relative error; share within 1/2/3 standard
 * errors). */
static void compare_dofs_with_truth(const rths_solution *sol, int dofs, const double *truth,
                                    point_stats *ps) {
    for (int d = 0; d < dofs && sol->interface_dofs == dofs; d++) {
        double a = sol->dof_amplitude_m[d], se = sol->dof_amplitude_se_m[d];
        if (!isfinite(truth[d]) || !(truth[d] > 0) || !isfinite(a)) continue;
        ps->dof_max_err[d] = fmax(ps->dof_max_err[d], fabs(a - truth[d]) / truth[d]);
        ps->dof_compared[d]++;
        for (int k = 1; k <= 3; k++)
            ps->dof_within[d][k] += se > 0 && fabs(a - truth[d]) <= k * se;
    }
}

/* summary.json's "interface_dofs" (the top-level counts are the first DoF's); NULL with one
 * interface DoF or a bilinear leg. */
static json_object *interface_dofs_json(const frf_state *run, const point_stats *ps) {
    const rths_setup *s = run->setup;
    int dofs = s->split.n_int;
    if (dofs < 2 || dofs > RTHS_MAX_INTERFACE_DOFS || s->has_bilinear) return NULL;
    json_object *arr = json_object_new_array();
    for (int d = 0; d < dofs; d++) {
        json_object *o = json_object_new_object();
        int dof = s->split.int_dofs[d];
        json_object_object_add(o, "interface_dof", json_object_new_int(d + 1));
        json_object_object_add(o, "dof", json_object_new_int(dof + 1));
        json_object_object_add(
            o, "unit", json_object_new_string(rths_setup_dof_is_rotation(s, dof) ? "rad" : "m"));
        json_object_object_add(o, "max_relative_error_vs_truth",
                               json_object_new_double(ps->dof_max_err[d]));
        json_object_object_add(o, "points_compared_with_truth",
                               json_object_new_int(ps->dof_compared[d]));
        json_object_object_add(o, "points_within_1_standard_error",
                               json_object_new_int(ps->dof_within[d][1]));
        json_object_object_add(o, "points_within_2_standard_errors",
                               json_object_new_int(ps->dof_within[d][2]));
        json_object_object_add(o, "points_within_3_standard_errors",
                               json_object_new_int(ps->dof_within[d][3]));
        json_object_array_add(arr, o);
    }
    return arr;
}

/* Totals and extremes over the accepted points; the largest error against the truth goes to
 * run->max_truth_error. */
static void point_statistics(frf_state *run, point_stats *ps) {
    const rths_truth_curve *t = &run->truth;
    const rths_setup *s = run->setup;
    memset(ps, 0, sizeof *ps);
    int *evals = calloc((size_t)(run->n ? run->n : 1), sizeof *evals);
    run->max_truth_error = 0;
    for (int i = 0; i < run->n; i++) {
        const rths_point *pt = &run->pts[i];
        ps->converged += pt->sol.converged;
        ps->measured_after_resume += pt->resumed;
        const rths_evaluation *acc = &pt->residual.eval;
        ps->late += acc->late_samples;
        ps->clipped += acc->clipped_demand_samples;
        ps->saturated += acc->saturated_sensor_samples;
        ps->samples_read += acc->samples_read;
        ps->points_late += acc->late_samples > 0;
        ps->points_clipped += acc->clipped_demand_samples > 0;
        ps->points_saturated += acc->saturated_sensor_samples > 0;
        ps->evaluations += pt->evaluations;
        ps->rig_time += pt->rig_time_s;
        if (evals) evals[i] = pt->evaluations;
        for (int k = 1; k <= 3; k++)
            ps->max_h[k] = fmax(ps->max_h[k], frf_harmonic_error(pt, k));
        /* a linear structure's analytic FRF, solved once for every use below (every interface
         * DoF's amplitude; NAN where it cannot be evaluated) */
        double f = pt->sol.frequency_hz, a = pt->sol.amplitude_m,
               truth[RTHS_MAX_INTERFACE_DOFS] = {NAN};
        int dofs = s->split.n_int, solved = !s->has_bilinear && dofs <= RTHS_MAX_INTERFACE_DOFS &&
                                            !rths_truth_linear_dof_amplitudes_m(s, f, truth);
        double e =
            s->has_bilinear ? rths_truth_curve_distance(t, f, a) : fabs(a - truth[0]) / truth[0];
        if (isfinite(e)) run->max_truth_error = fmax(run->max_truth_error, e);
        ps->honest += pt->sol.amplitude_se_honest;
        compare_with_truth(run, pt, truth[0], ps);
        if (solved && dofs > 1) compare_dofs_with_truth(&pt->sol, dofs, truth, ps);
    }
    if (evals && run->n) {
        qsort(evals, (size_t)run->n, sizeof *evals, compare_int);
        ps->median =
            run->n % 2 ? evals[run->n / 2] : 0.5 * (evals[run->n / 2 - 1] + evals[run->n / 2]);
    }
    free(evals);
}

/* The folds: where this process located them, else (a resumed journal's flag without a located
 * fold) the midpoint of the bracketing points. */
static json_object *folds_json(const frf_state *run) {
    const rths_continuation_result *res = &run->result;
    json_object *folds = json_object_new_array();
    for (int i = 0; i < run->n; i++) {
        if (!run->pts[i].fold) continue;
        double f = 0, a = 0;
        int found = 0;
        for (int k = 0; k < res->n_folds; k++)
            if (res->folds[k].after_point == i) {
                f = res->folds[k].frequency_hz;
                a = res->folds[k].amplitude_m;
                found = 1;
            }
        if (!found && i + 1 < run->n) {
            f = 0.25 * (run->pts[i].sol.omega_rad_s + run->pts[i + 1].sol.omega_rad_s) / M_PI;
            a = 0.5 *
                (rths_point_amplitude_m(&run->pts[i]) + rths_point_amplitude_m(&run->pts[i + 1]));
        }
        json_object *fold = json_object_new_object();
        json_object_object_add(fold, "frequency_hz", json_object_new_double(f));
        json_object_object_add(fold, "amplitude_m", json_object_new_double(a));
        json_object_object_add(fold, "after_point", json_object_new_int(i));
        json_object_array_add(folds, fold);
    }
    return folds;
}

/* The standard errors and stability labels against the truth at each point's frequency on its
 * branch (the analytic FRF, or the shooting curve with its Floquet stability). */
static void add_truth_comparison(json_object *root, const point_stats *ps) {
    json_object_object_add(root, "points_compared_with_truth", json_object_new_int(ps->compared));
    json_object_object_add(root, "points_within_1_standard_error",
                           json_object_new_int(ps->within_se[1]));
    json_object_object_add(root, "points_within_2_standard_errors",
                           json_object_new_int(ps->within_se[2]));
    json_object_object_add(root, "points_within_3_standard_errors",
                           json_object_new_int(ps->within_se[3]));
    json_object_object_add(root, "points_with_honest_standard_error",
                           json_object_new_int(ps->honest));
    json_object_object_add(root, "points_far_from_folds", json_object_new_int(ps->far));
    json_object_object_add(root, "points_far_from_folds_within_3_standard_errors",
                           json_object_new_int(ps->far_within_3se));
    json_object_object_add(root, "max_deviation_in_standard_errors",
                           json_object_new_double(ps->max_z_honest));
    json_object_object_add(root, "stability_points_compared",
                           json_object_new_int(ps->stable_compared));
    json_object_object_add(root, "stability_points_agreeing",
                           json_object_new_int(ps->stable_agree));
}

/* The integrity counts: every period the rig delivered in this process (refused evaluations,
 * failed corrections and the trace's settling included; a resume counts its own), and the
 * accepted evaluations' (journaled, so resumed points included). */
static json_object *integrity_json(const frf_state *run, const point_stats *ps) {
    rths_rig_integrity t;
    rths_rig_integrity_totals(run->rig, &t);
    json_object *o = json_object_new_object(), *rig = json_object_new_object(),
                *acc = json_object_new_object();
    json_object_object_add(rig, "periods", json_object_new_int64(t.periods));
    json_object_object_add(rig, "samples", json_object_new_int64(t.samples));
    json_object_object_add(rig, "late_samples", json_object_new_int64(t.late_samples));
    json_object_object_add(rig, "clipped_demand_samples",
                           json_object_new_int64(t.clipped_demand_samples));
    json_object_object_add(rig, "saturated_sensor_samples",
                           json_object_new_int64(t.saturated_sensor_samples));
    json_object_object_add(o, "rig_this_run", rig);
    json_object_object_add(acc, "samples_read", json_object_new_int64(ps->samples_read));
    json_object_object_add(acc, "late_samples", json_object_new_int64(ps->late));
    json_object_object_add(acc, "clipped_demand_samples", json_object_new_int64(ps->clipped));
    json_object_object_add(acc, "saturated_sensor_samples", json_object_new_int64(ps->saturated));
    json_object_object_add(acc, "points_with_late_samples", json_object_new_int(ps->points_late));
    json_object_object_add(acc, "points_with_clipped_demand",
                           json_object_new_int(ps->points_clipped));
    json_object_object_add(acc, "points_with_saturated_sensors",
                           json_object_new_int(ps->points_saturated));
    json_object_object_add(o, "accepted_points", acc);
    return o;
}

/* How the points' evaluations reached steady state (rths_point.settle, journaled, so resumed
 * points included; docs/method.md, "The fitted evaluation"): the accepted evaluations fitted or
 * waited, the points with any fallback to waiting, and with iteration.target_rel_se the points
 * whose accepted evaluation stayed above it within the point's iteration.max_rig_s_per_point. */
static json_object *evaluation_json(const frf_state *run) {
    int fitted = 0, fell_back = 0, missed = 0, evals = 0, evals_fitted = 0, evals_fallback = 0,
        evals_missed = 0, over = 0;
    double budget = run->settle.max_rig_s_per_point > 0 ? run->settle.max_rig_s_per_point
                                                        : RTHS_SETTLE_MAX_RIG_S_PER_POINT;
    for (int i = 0; i < run->n; i++) {
        const rths_point *pt = &run->pts[i];
        fitted += pt->sol.eval.fitted;
        fell_back += pt->settle.fit_fallbacks > 0 || pt->sol.eval.fit_fallback;
        missed += pt->sol.eval.se_target_missed;
        evals += pt->settle.evaluations;
        evals_fitted += pt->settle.fitted;
        evals_fallback += pt->settle.fit_fallbacks;
        evals_missed += pt->settle.se_target_missed;
        over += pt->rig_time_s > budget;
    }
    json_object *o = json_object_new_object();
    json_object_object_add(
        o, "strategy",
        json_object_new_string(run->settle.strategy == RTHS_SETTLE_FIT ? "fit" : "wait"));
    json_object_object_add(o, "points_fitted", json_object_new_int(fitted));
    json_object_object_add(o, "points_waited", json_object_new_int(run->n - fitted));
    json_object_object_add(o, "points_with_fit_fallback", json_object_new_int(fell_back));
    json_object_object_add(o, "evaluations", json_object_new_int(evals));
    json_object_object_add(o, "evaluations_fitted", json_object_new_int(evals_fitted));
    json_object_object_add(o, "evaluations_fit_fallback", json_object_new_int(evals_fallback));
    json_object_object_add(o, "target_rel_se", json_object_new_double(run->settle.target_rel_se));
    json_object_object_add(o, "max_rig_s_per_point", json_object_new_double(budget));
    json_object_object_add(o, "points_se_target_missed", json_object_new_int(missed));
    json_object_object_add(o, "evaluations_se_target_missed", json_object_new_int(evals_missed));
    json_object_object_add(o, "points_over_max_rig_s", json_object_new_int(over));
    return o;
}

void frf_log_integrity(frf_state *run) {
    rths_rig_integrity t;
    rths_rig_integrity_totals(run->rig, &t);
    long late = 0, clipped = 0, saturated = 0;
    for (int i = 0; i < run->n; i++) {
        late += run->pts[i].residual.eval.late_samples;
        clipped += run->pts[i].residual.eval.clipped_demand_samples;
        saturated += run->pts[i].residual.eval.saturated_sensor_samples;
    }
    rths_report_log(run->rep,
                    "integrity: the rig ran %ld periods (%ld samples) in this run: %ld late, %ld "
                    "with a clipped demand, %ld with a saturated sensor; the accepted points' "
                    "evaluations: %ld late, %ld clipped-demand, %ld saturated-sensor samples",
                    t.periods, t.samples, t.late_samples, t.clipped_demand_samples,
                    t.saturated_sensor_samples, late, clipped, saturated);
}

void frf_integrity_to_error(frf_state *run, rths_error *err) {
    rths_rig_integrity t;
    rths_rig_integrity_totals(run->rig, &t);
    if (!t.late_samples && !t.clipped_demand_samples && !t.saturated_sensor_samples) return;
    size_t len = strlen(err->msg);
    snprintf(err->msg + len, sizeof err->msg - len,
             "; the rig reported %ld late, %ld clipped-demand and %ld saturated-sensor samples "
             "of %ld in this run (an evaluation with clipping or overruns is refused)",
             t.late_samples, t.clipped_demand_samples, t.saturated_sensor_samples, t.samples);
}

/* What the virtual rig's actuator limits saw over the run (rig.actuator.limits): samples clipped
 * or flagged, and the peaks, so a test that ran near its limits says so. */
static json_object *actuator_summary(const rths_plant *plant) {
    rths_actuator_status st;
    rths_plant_actuator_status(plant, &st);
    json_object *o = json_object_new_object();
    json_object_object_add(o, "force_clipped_samples",
                           json_object_new_int64(st.force_clipped_samples));
    json_object_object_add(o, "stroke_flagged_samples",
                           json_object_new_int64(st.stroke_flagged_samples));
    json_object_object_add(o, "velocity_flagged_samples",
                           json_object_new_int64(st.velocity_flagged_samples));
    json_object_object_add(o, "peak_force_n", json_object_new_double(st.peak_force_n));
    json_object_object_add(o, "peak_stroke_m", json_object_new_double(st.peak_stroke_m));
    json_object_object_add(o, "peak_velocity_m_per_s",
                           json_object_new_double(st.peak_velocity_m_per_s));
    return o;
}

int frf_write_summary(frf_state *run, rths_error *err) {
    const frf_state *facts = run;
    const rths_continuation_result *res = &run->result;
    json_object *root = summary_new(run->opt);
    point_stats ps;
    point_statistics(run, &ps);
    int converged = ps.converged, evaluations = ps.evaluations;
    double rig_time = ps.rig_time, median = ps.median, *max_h = ps.max_h;
    double *max_truth_error = &run->max_truth_error;
    json_object_object_add(root, "strategy", json_object_new_string(facts->strategy));
    json_object_object_add(root, "harmonics", json_object_new_int(facts->harmonics));
    json_object_object_add(root, "mass_ratio",
                           json_object_new_double(facts->setup->split.mass_ratio));
    rths_summary_add_excitation(root, facts->setup);
    json_object_object_add(root, "bilinear", json_object_new_boolean(facts->setup->has_bilinear));
    json_object_object_add(root, "points", json_object_new_int(run->n));
    json_object_object_add(root, "converged_points", json_object_new_int(converged));
    json_object_object_add(root, "resumed_points", json_object_new_int(facts->n_resume));
    json_object_object_add(root, "points_measured_after_resume",
                           json_object_new_int(ps.measured_after_resume));
    json_object_object_add(root, "integrity", integrity_json(run, &ps));
    json_object_object_add(root, "evaluation", evaluation_json(run));
    /* Totals over the accepted points (journal included on --resume); failed attempts are in
     * their point's counts, since a point's counters include its retries. */
    json_object_object_add(root, "evaluations_total", json_object_new_int(evaluations));
    json_object_object_add(root, "evaluations_per_point_median", json_object_new_double(median));
    json_object_object_add(root, "evaluations_per_point_mean",
                           json_object_new_double(run->n ? (double)evaluations / run->n : 0));
    json_object_object_add(root, "rig_time_s", json_object_new_double(rig_time));
    json_object_object_add(root, "rig_time_per_point_s",
                           json_object_new_double(run->n ? rig_time / run->n : 0));
    json_object_object_add(root, "trace_rig_time_s",
                           json_object_new_double(facts->trace_rig_time_s));
    json_object_object_add(root, "wall_time_s", json_object_new_double(facts->wall_time_s));
    rths_plant *plant = run->virtual_rig ? rths_virtual_rig_plant(run->virtual_rig) : NULL;
    if (plant) json_object_object_add(root, "actuator", actuator_summary(plant));
    json_object_object_add(root, "failed_corrections", json_object_new_int(res->failures));
    json_object_object_add(root, "reached_end", json_object_new_boolean(res->reached_end));
    /* short of the end by failures or the range (the run failed, exit 1; stop_reason says why) */
    json_object_object_add(root, "stopped_short", json_object_new_boolean(res->stopped_short));
    json_object_object_add(root, "stop_reason", json_object_new_string(res->stop_reason));
    json_object_object_add(root, "folds", folds_json(run));
    json_object_object_add(root, "max_interface_error_h1_m", json_object_new_double(max_h[1]));
    json_object_object_add(root, "max_interface_error_h2_m", json_object_new_double(max_h[2]));
    json_object_object_add(root, "max_interface_error_h3_m", json_object_new_double(max_h[3]));
    json_object_object_add(
        root, "truth",
        json_object_new_string(facts->setup->has_bilinear
                                   ? "shooting with the bilinear leg (truth.csv)"
                                   : "analytic FRF of the assembly (truth.csv)"));
    json_object_object_add(root, "max_relative_error_vs_truth",
                           json_object_new_double(*max_truth_error));
    json_object_object_add(
        root, "amplitude_reported",
        json_object_new_string(facts->newton.report_matched
                                   ? "matched: the physical interface response extrapolated to "
                                     "zero interface mismatch through the corrector's Jacobians"
                                   : "measured: the physical interface response at the accepted "
                                     "target"));
    add_truth_comparison(root, &ps);
    json_object *per_dof = interface_dofs_json(run, &ps);
    if (per_dof) json_object_object_add(root, "interface_dofs", per_dof);
    if (run->floquet.enabled) {
        floquet_statistics(run, &ps);
        json_object_object_add(root, "experimental_floquet", floquet_json(run, &ps));
    }
    json_object_object_add(
        root, "truth_error_measure",
        json_object_new_string(facts->setup->has_bilinear
                                   ? "distance to the truth curve in the plane (10 ln f, ln A): "
                                     "1 % in amplitude or 0.1 % in frequency count alike"
                                   : "|A - A_true(f)| / A_true(f) at each point's frequency"));
    int rc = write_summary_json(run->rep, root, err);
    json_object_put(root);
    return rc;
}
